"""
ROS 2 parameter files, read alike by ``sim_node`` and the offline command, and the path rule.

A parameter file is ROS 2's YAML (``<node>: {ros__parameters: {...}}``, ``/**`` for every
node); :class:`RosParamLoader` reads ``2.8e6`` and ``1e-3`` as numbers, as ROS 2 does (PyYAML's
YAML 1.1 rules would read them as strings). :func:`simulator_params` gives the simulator's
parameters of a file (the offline command builds its configuration from them); ``sim_node``
gets the same file-input values (:func:`train_dynamics.ros.executor.file_input_args`).

The path rule, one for every parameter naming a file to read (``file_input`` in the table:
``consist_file``), the same in the node and offline. A relative path is relative to

- the folder of the parameter file, when the value came from a parameter file (``--params``
  of the offline command, ``--params-file`` of the node: resolved when the file is read);
- else (``ros2 param set``, ``-p``, a sweep file's grid, Python) the current directory;

and when it is not there, the shipped ``config/`` folder (:func:`config_dirs`: source tree,
then installed share). An absolute path is used as is. The value kept in the configuration is
then the absolute path of the file found. (``record_bag`` is an output, relative to the
current directory as ``ros2 bag record -o`` is.)

Never imports rclpy.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import sys
from typing import Any, Callable, Mapping

from train_dynamics import topics
from train_dynamics.physics.config.spec import ConfigError, ParamSpec
from train_dynamics.physics.config.table import PARAMETERS
from train_dynamics.quoting import quote
import yaml


class RosParamLoader(yaml.SafeLoader):
    """A safe YAML loader that reads 2.8e6 and 1e-3 as floats, as ROS 2's parser does."""


class FastRosParamLoader(getattr(yaml, 'CSafeLoader', yaml.SafeLoader)):
    """:class:`RosParamLoader` on libyaml's parser (~6x faster): for files that may be long."""


for _loader in (RosParamLoader, FastRosParamLoader):
    _loader.add_implicit_resolver(
        'tag:yaml.org,2002:float',
        re.compile(r'^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$'),
        list('-+0123456789'))


#: parameters every ROS 2 node has; a parameter file may set them, the model ignores them
ROS_BUILTIN_PARAMETERS = ('use_sim_time', 'start_type_description_service')

#: node names whose sections a parameter file of this package may hold ('/**': every node)
KNOWN_NODE_NAMES = (topics.NODE_NAME, topics.VALVE_NODE_NAME)
WILDCARD = '/**'


# -- the path rule ---------------------------------------------------------------------------

def config_dirs() -> list[Path]:
    """Return the folders holding the shipped ``config/`` files: source tree, then installed."""
    dirs = [Path(__file__).resolve().parents[3] / 'config']
    try:   # optional: only present in a sourced ROS 2 environment
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory('train_dynamics')) / 'config')
    except Exception:  # noqa: B902 - not installed, or the package is not in the index
        pass
    dirs.append(Path(sys.prefix) / 'share' / 'train_dynamics' / 'config')
    return dirs


def resolve_path(name: str, base_dir: str | None = None, what: str = 'consist_file') -> Path:
    """
    Return the file ``name`` (the path rule): absolute, else in ``base_dir`` or cwd, else config/.

    ``base_dir``: the folder of the parameter file the value came from, None for any other
    source. Raises :class:`ConfigError` naming ``what`` and the folders looked in.
    """
    path = Path(os.path.expanduser(name))
    if path.is_absolute():
        if _is_file(path):
            return path
        raise ConfigError(f'{what}: file not found: {quote(str(path))}')
    folders = [Path(base_dir or os.getcwd())] + config_dirs()
    for folder in folders:
        if _is_file(folder / path):
            return (folder / path).absolute()
    raise ConfigError(f'{what}: {quote(name)} not found (looked in '
                      f'{", ".join(str(f) for f in folders)})')


def _is_file(path: Path) -> bool:
    """Return True if ``path`` is a file; False for a name the system refuses (too long)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def resolve_file_inputs(params: Mapping[str, Any], base_dir: str,
                        specs: Mapping[str, ParamSpec] = PARAMETERS) -> dict[str, str]:
    """Return ``{name: absolute path}`` of the non-empty relative file inputs of ``params``."""
    out = {}
    for name, value in params.items():
        spec = specs.get(name)
        if (spec is not None and spec.file_input and isinstance(value, str) and value
                and not os.path.isabs(os.path.expanduser(value))):
            out[name] = str(resolve_path(value, base_dir, name))
    return out


# -- reading parameter files -----------------------------------------------------------------

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
