"""
The layering rule of the package, checked in fresh interpreters and in the source.

``topics`` <- ``physics`` <- ``simulation`` <- ``recording`` <- ``ros`` / ``cli``: the physics
and simulation layers never load rclpy, rosbags or matplotlib; the recording layer never loads
rclpy; ``topics`` loads nothing of the project or of third parties. Only ``ros/`` imports
rclpy.
"""
from __future__ import annotations

import json
from pathlib import Path
import pkgutil
import re
import subprocess
import sys

import pytest

import train_dynamics

PACKAGE = Path(train_dynamics.__file__).resolve().parent
REPO = PACKAGE.parent

#: package -> top-level modules it must never load (directly or through anything it imports)
FORBIDDEN = {
    'train_dynamics.physics': ('rclpy', 'rosbags', 'matplotlib'),
    'train_dynamics.simulation': ('rclpy', 'rosbags', 'matplotlib'),
    'train_dynamics.recording': ('rclpy',),
}
#: folder -> top-level modules its files must never name in an import line
FORBIDDEN_IMPORT_LINES = {
    'physics': ('rclpy', 'rosbags', 'matplotlib'),
    'simulation': ('rclpy', 'rosbags', 'matplotlib'),
    'recording': ('rclpy',),
}

_PROBE = """
import importlib, json, sys
before = set(sys.modules)
for name in sys.argv[1:]:
    importlib.import_module(name)
print(json.dumps(sorted(set(sys.modules) - before)))
"""


def loaded_by(*modules: str) -> set[str]:
    """Return the modules newly loaded by importing ``modules`` in a fresh interpreter."""
    proc = subprocess.run([sys.executable, '-c', _PROBE, *modules], capture_output=True,
                          text=True, cwd=REPO, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return set(json.loads(proc.stdout.splitlines()[-1]))


def modules_of(package: str) -> list[str]:
    """Return the package and every module in it (by file, without importing them)."""
    folder = PACKAGE / package.rsplit('.', 1)[-1]
    return [package] + [f'{package}.{m.name}' for m in pkgutil.iter_modules([str(folder)])]


def roots(modules: set[str]) -> set[str]:
    """Return the top-level names of ``modules``."""
    return {m.split('.', 1)[0] for m in modules}


@pytest.mark.parametrize('package', sorted(FORBIDDEN))
def test_layer_loads_no_forbidden_module(package):
    modules = modules_of(package)
    assert len(modules) > 1, modules             # the probe sees the layer's modules
    bad = roots(loaded_by(*modules)) & set(FORBIDDEN[package])
    assert not bad, f'importing {package} loads {sorted(bad)}'


def test_topics_loads_only_the_standard_library():
    new = loaded_by('train_dynamics.topics')
    project = sorted(m for m in new if m.startswith('train_dynamics')
                     and m not in ('train_dynamics', 'train_dynamics.topics'))
    assert not project, project
    third_party = sorted(m for m in roots(new) - {'train_dynamics'}
                         if m not in sys.stdlib_module_names and not m.startswith('_'))
    assert not third_party, third_party


def test_the_probe_sees_a_forbidden_import():
    # the check above can fail: importing the node loads rclpy
    assert 'rclpy' in roots(loaded_by('train_dynamics.ros.sim_node'))


_IMPORT_LINE = re.compile(r'^\s*(?:import\s+([\w.]+)|from\s+([\w.]+)\s+import\b)', re.M)


def import_lines(path: Path) -> set[str]:
    """Return the top-level names of every module that the file's import lines name."""
    text = path.read_text(encoding='utf-8')
    return {(a or b).split('.', 1)[0] for a, b in _IMPORT_LINE.findall(text)}


@pytest.mark.parametrize('folder', sorted(FORBIDDEN_IMPORT_LINES))
def test_no_forbidden_import_line_in_the_source(folder):
    files = sorted((PACKAGE / folder).rglob('*.py'))
    assert files
    bad = {str(f.relative_to(REPO)): sorted(import_lines(f) & set(FORBIDDEN_IMPORT_LINES[folder]))
           for f in files}
    assert not {f: names for f, names in bad.items() if names}


def test_import_line_scan_sees_indented_imports():
    text = 'def f():\n    import rclpy.node\n    from rosbags.typesys import Stores\n'
    names = {(a or b).split('.', 1)[0] for a, b in _IMPORT_LINE.findall(text)}
    assert names == {'rclpy', 'rosbags'}


def test_parameter_files_layer_loads_no_ros_and_physics_knows_not_their_form():
    # the ROS 2 parameter-file form is read by train_dynamics.param_files, for cli and ros
    # alike, without rclpy; the physics never sees a `<node>: ros__parameters:` nesting
    bad = roots(loaded_by('train_dynamics.param_files')) & {'rclpy', 'rosbags', 'matplotlib'}
    assert not bad, bad
    named = [str(f.relative_to(REPO)) for f in sorted((PACKAGE / 'physics').rglob('*.py'))
             if 'ros__parameters' in f.read_text(encoding='utf-8')]
    assert not named, named
