"""
YAML files of the configuration (consist files, vehicle library): the dialect, the path rule.

:class:`RosParamLoader` reads ``2.8e6`` and ``1e-3`` as numbers, as ROS 2's parser does
(PyYAML's YAML 1.1 rules would read them as strings), so that a consist file, the vehicle
library and a parameter file read a number alike. The form of a ROS 2 parameter file (its
node sections) is not known here: :mod:`train_dynamics.param_files`
reads it, for the nodes and the offline command alike.

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
from typing import Any, Mapping

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
