"""
ROS 2 parameter files, read alike by the nodes, the offline command and the controller harness.

A parameter file is ROS 2's YAML: ``<node>: {ros__parameters: {...}}`` sections, ``/**`` for
every node, ``/ns/node`` for a namespaced one (more specific sections win). This module knows
that form and the node names of the package; the configuration below it
(:mod:`train_dynamics.physics.config`) knows neither: it takes the ``{name: value}`` mapping
:func:`simulator_params` returns. Numbers are read as ROS 2 reads them
(:class:`~train_dynamics.physics.config.files.RosParamLoader`); relative file inputs
(``consist_file``) are made absolute by the path rule of
:mod:`train_dynamics.physics.config.files` against the file's folder.

- :func:`load_param_file`: the simulator's configuration of a file (the offline command, the
  tests);
- :func:`simulator_params`, :func:`valve_params`: the parameters of each node's sections;
- :func:`read_param_sections`, :func:`node_sections`, :func:`unknown_sections`: the sections,
  for ``sim_node``'s ``--params-file`` checks (:mod:`train_dynamics.ros.executor`).

Between the configuration and its users: imports ``topics`` and ``physics``, never rclpy or
rosbags (``sim_node`` gives a file to rclpy and reads it here only for the checks rclpy does
not make).
"""
from __future__ import annotations

import os
from typing import Any, Callable, Mapping

from train_dynamics import topics
from train_dynamics.physics.brake_valve import BrakeValveModel, VALVE_PARAMETERS
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig
from train_dynamics.physics.config.files import resolve_file_inputs, RosParamLoader
from train_dynamics.quoting import quote
import yaml

#: parameters every ROS 2 node has; a parameter file may set them, the model ignores them
ROS_BUILTIN_PARAMETERS = ('use_sim_time', 'start_type_description_service')

#: node names whose sections a parameter file of this package may hold ('/**': every node)
KNOWN_NODE_NAMES = (topics.NODE_NAME, topics.VALVE_NODE_NAME)
WILDCARD = '/**'


def read_param_sections(path: str) -> dict[str, dict[str, Any]]:
    """
    Return ``{section: ros__parameters}`` of a ROS 2 parameter file, in file order.

    Raises :class:`ConfigError` (one line) for a missing, unreadable or malformed file: what
    rclpy would refuse with an ``RCLError``.
    """
    try:
        with open(path, encoding='utf-8') as fh:
            doc = yaml.load(fh, Loader=RosParamLoader)
    except FileNotFoundError:
        raise ConfigError(f'parameter file not found: {path}') from None
    except IsADirectoryError:
        raise ConfigError(f'parameter file {path} is a directory') from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(' '.join(f'cannot read parameter file {path}: {exc}'.split())
                          ) from None
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{path}: not a ROS 2 parameter file (top level is not a mapping)')
    sections: dict[str, dict[str, Any]] = {}
    for key, section in doc.items():
        if not isinstance(key, str):
            raise ConfigError(f'{path}: section name {quote(key)} is not a node name')
        if not isinstance(section, dict) or 'ros__parameters' not in section:
            raise ConfigError(f'{path}: section {quote(key)} has no ros__parameters')
        params = section['ros__parameters'] or {}
        if not isinstance(params, dict):
            raise ConfigError(f'{path}: {key}.ros__parameters is not a mapping')
        sections[key] = params
    return sections


def section_node(key: str) -> str:
    """Return the node name of a parameter-file section: '/ns/node' -> 'node'."""
    return key.rstrip('/').split('/')[-1]


def unknown_sections(sections: Mapping[str, Any],
                     known: tuple[str, ...] = KNOWN_NODE_NAMES) -> list[str]:
    """Return the sections that apply to none of the ``known`` nodes (e.g. a typo)."""
    return [k for k in sections if k != WILDCARD and section_node(k) not in known]


def unknown_sections_message(path: str, unknown: list[str]) -> str:
    """Return the one-line warning about sections for no node of this package."""
    return (f'{path}: section(s) {", ".join(quote(k) for k in unknown)} match no node of this '
            f'package and are ignored (known: {", ".join(KNOWN_NODE_NAMES)}, {WILDCARD})')


def node_sections(sections: Mapping[str, dict[str, Any]], node_name: str
                  ) -> tuple[dict[str, Any], dict[str, Any]]:
    """
    Return (the ``/**`` parameters, the node's own) of ``sections`` for ``node_name``.

    Own: the sections ``node``, ``/node`` and ``/ns/node``, later ones winning.
    """
    own: dict[str, Any] = {}
    for key, params in sections.items():
        if key != WILDCARD and section_node(key) == node_name:
            own.update(params)
    return dict(sections.get(WILDCARD, {})), own


def read_param_file(path: str, node_name: str = topics.NODE_NAME) -> dict[str, Any]:
    """
    Read the ``ros__parameters`` of ``node_name`` from a ROS 2 parameter file.

    Accepts the node's own key, ``/node``, a namespaced ``/ns/node`` and the ``/**``
    wildcard (more specific sections win). Returns ``{}`` when the node has no section.
    Raises :class:`ConfigError` for a missing or malformed file.
    """
    wildcard, own = node_sections(read_param_sections(path), node_name)
    return {**wildcard, **own}


def simulator_params(path: str, warn: Callable[[str], None] | None = None) -> dict[str, Any]:
    """
    Return the simulator's parameters (``train_dynamics``) of a ROS 2 parameter file.

    As rclpy does for the node: keys of the ``/**`` section that the simulator does not
    declare are ignored (they may be the brake valve's). Unlike rclpy, a file whose only
    sections match no node of this package (a typo such as ``train_dynamic:``) is an error;
    other unknown sections are reported through ``warn``. Unknown keys of the node's own
    section are returned (the configuration refuses them). Relative file inputs are made
    absolute by the path rule (the file's folder).
    """
    sections = read_param_sections(path)
    unknown = unknown_sections(sections)
    wildcard, own = node_sections(sections, topics.NODE_NAME)
    if unknown:
        if len(unknown) == len(sections):
            raise ConfigError(
                f'{path}: no section for {topics.NODE_NAME}, only '
                f'{", ".join(quote(k) for k in unknown)} (known: {", ".join(KNOWN_NODE_NAMES)}, '
                f'{WILDCARD}); a typo?')
        if warn is not None:
            warn(unknown_sections_message(path, unknown))
    params = {k: v for k, v in wildcard.items() if k in PARAMETERS}
    params.update({k: v for k, v in own.items() if k not in ROS_BUILTIN_PARAMETERS})
    try:
        params.update(resolve_file_inputs(params, os.path.dirname(os.path.abspath(path))))
    except ConfigError as exc:
        raise ConfigError(f'{path}: {exc}') from None
    return params


def load_param_file(path: str, warn: Callable[[str], None] | None = None) -> SimConfig:
    """
    Read the simulator configuration from a ROS 2 parameter file (``train_dynamics``).

    The file is read by :func:`simulator_params` (its rules for sections, unknown keys and
    relative paths); an unknown key of the node's own section is an error. ConfigError
    messages name the file.
    """
    params = simulator_params(path, warn)
    try:
        return SimConfig.from_dict(params)
    except ConfigError as exc:
        raise ConfigError(f'{path}: {exc}') from None


def valve_params(path: str, node_name: str = topics.VALVE_NODE_NAME) -> dict[str, Any]:
    """
    Return the brake valve's parameters of a ROS 2 parameter file ({} without a section).

    As rclpy does for the node: keys of the ``/**`` section the valve does not declare are
    not its concern; the parameters every ROS 2 node has (``use_sim_time``) are dropped. The
    other keys of its own section are returned (:meth:`BrakeValveModel.from_params` with
    ``strict`` refuses unknown ones). Raises :class:`ConfigError` for a malformed file.
    """
    wildcard, own = node_sections(read_param_sections(path), node_name)
    params = {k: v for k, v in wildcard.items() if k in VALVE_PARAMETERS}
    params.update({k: v for k, v in own.items() if k not in ROS_BUILTIN_PARAMETERS})
    return params


def load_valve_model(path: str, node_name: str = topics.VALVE_NODE_NAME) -> BrakeValveModel:
    """Build the brake valve of the ``node_name`` section of a parameter file ({} -> defaults)."""
    try:
        return BrakeValveModel.from_params(valve_params(path, node_name))
    except ValueError as exc:
        raise ValueError(f'{path}: {node_name}: {exc}') from None
