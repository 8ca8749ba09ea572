"""
The package as ROS 2 tooling sees it: package.xml's dependencies, rosdep keys, launch files.

- every module the package imports (``train_dynamics/``, ``launch/``; and the package of
  every message type the topic table names, imported by name) maps to a run dependency of
  package.xml, every module the tests import to a run or test dependency, and
  no dependency is unused; a module without a rosdep key is installed with pip from
  requirements.txt (checked against ros/rosdistro ``rosdep/python.yaml``);
- the documents name rosbags' rosdep key (``python3-rosbags-pip``) alike: none says it has
  none;
- the launch files declare ``namespace``, ``use_sim_time`` and ``params_file`` and use them
  (statically: ``launch_ros`` is not in the wheels).
"""
from __future__ import annotations

import ast
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ET

import pytest

REPO = Path(__file__).resolve().parents[2]
#: no rosdep key (ros/rosdistro rosdep/python.yaml has none): pip, from requirements.txt
PIP_ONLY = 'pip'
#: top-level module -> the rosdep key that installs it
IMPORT_KEYS = {
    'rclpy': 'rclpy', 'rcl_interfaces': 'rcl_interfaces', 'sensor_msgs': 'sensor_msgs',
    'std_msgs': 'std_msgs', 'std_srvs': 'std_srvs', 'diagnostic_msgs': 'diagnostic_msgs',
    'rosgraph_msgs': 'rosgraph_msgs', 'builtin_interfaces': 'builtin_interfaces',
    'nav_msgs': 'nav_msgs', 'geometry_msgs': 'geometry_msgs',
    'train_dynamics_msgs': 'train_dynamics_msgs',
    'ament_index_python': 'ament_index_python', 'launch': 'launch', 'launch_ros': 'launch_ros',
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'numba': 'python3-numba',
    'llvmlite': 'python3-numba',          # a dependency of numba's Debian package
    'matplotlib': 'python3-matplotlib', 'yaml': 'python3-yaml',
    'ruamel': 'python3-ruamel.yaml', 'rosbags': 'python3-rosbags-pip', 'tqdm': 'python3-tqdm',
    'pandas': 'python3-pandas', 'psutil': 'python3-psutil', 'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis', 'ament_flake8': 'ament_flake8',
    'ament_pep257': 'ament_pep257',
    'dask': PIP_ONLY, 'distributed': PIP_ONLY, 'pyarrow': PIP_ONLY,
}
#: the pip distribution of each PIP_ONLY module (requirements.txt names it)
PIP_NAMES = {'dask': 'dask', 'distributed': 'distributed', 'pyarrow': 'pyarrow'}
#: test dependencies no test imports: pytest plugins
PLUGINS = {'python3-pytest-timeout'}


def _depends(kind: str) -> set[str]:
    root = ET.parse(REPO / 'package.xml').getroot()
    return {e.text.strip() for e in root.iter() if e.tag in (kind, 'depend')}


def _own_package(path: Path) -> bool:
    """Return True for a file of a package of its own (a ``package.xml`` above it in test/)."""
    return any((folder / 'package.xml').is_file() for folder in path.parents
               if folder != REPO and REPO in folder.parents)


def _imports(paths) -> dict[str, list[str]]:
    """
    Return top-level module -> files, for the absolute imports outside the stdlib.

    A file of a package of its own (test/downstream/...: its package.xml declares its
    dependencies) is not counted.
    """
    found: dict[str, list[str]] = {}
    for path in (p for p in paths if not _own_package(p)):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top not in sys.stdlib_module_names:
                    found.setdefault(top, []).append(str(path.relative_to(REPO)))
    return found


def _message_packages() -> dict[str, list[str]]:
    """Return the packages of the message types the topic table names (imported by name)."""
    text = (REPO / 'train_dynamics' / 'topics.py').read_text(encoding='utf-8')
    return {pkg: ['train_dynamics/topics.py']
            for pkg in re.findall(r"'(\w+)/(?:msg|srv)/\w+'", text)}


def _local_modules() -> set[str]:
    """Return the package and the tests' helper modules (no test imports a benchmark)."""
    return {'train_dynamics'} | {p.stem for p in (REPO / 'test').glob('*.py')}


def test_every_import_maps_to_a_dependency_and_none_is_unused():
    code = _imports([*(REPO / 'train_dynamics').rglob('*.py'), *(REPO / 'launch').glob('*.py')])
    for pkg, where in _message_packages().items():      # imported by type name at run time
        code.setdefault(pkg, where)
    tests = _imports([*(REPO / 'test').rglob('*.py'), *(REPO / 'examples').glob('*.py')])
    for found in (code, tests):
        for name in _local_modules():
            found.pop(name, None)
    unmapped = sorted((set(code) | set(tests)) - set(IMPORT_KEYS))
    assert not unmapped, f'no rosdep key known for {unmapped}: add it to IMPORT_KEYS'
    run, test = _depends('exec_depend'), _depends('test_depend')
    missing = sorted(f'{IMPORT_KEYS[m]} ({code[m][0]})' for m in code
                     if IMPORT_KEYS[m] != PIP_ONLY and IMPORT_KEYS[m] not in run)
    assert not missing, f'package.xml lacks <exec_depend> {missing}'
    missing = sorted(f'{IMPORT_KEYS[m]} ({tests[m][0]})' for m in tests
                     if IMPORT_KEYS[m] != PIP_ONLY and IMPORT_KEYS[m] not in run | test)
    assert not missing, f'package.xml lacks <test_depend> {missing}'
    requirements = (REPO / 'requirements.txt').read_text(encoding='utf-8')
    for module in [m for m in code if IMPORT_KEYS[m] == PIP_ONLY]:
        assert re.search(rf'^{PIP_NAMES[module]}==', requirements, re.M), module
    used = {IMPORT_KEYS[m] for m in code}
    assert run <= used, f'<exec_depend> nothing imports: {sorted(run - used)}'
    used |= {IMPORT_KEYS[m] for m in tests} | PLUGINS
    assert test <= used, f'<test_depend> nothing imports: {sorted(test - used)}'


def test_documents_agree_on_the_rosbags_rosdep_key():
    """Name python3-rosbags-pip: rosdep installs rosbags with pip through it (ros/rosdistro)."""
    pages = ['README.md', 'docs/install.md', 'requirements.txt', 'package.xml']
    for page in pages:
        text = ' '.join((REPO / page).read_text(encoding='utf-8').split())
        assert 'python3-rosbags-pip' in text, page
        assert not re.search(r'rosbags[^.]{0,80}\bno rosdep key', text), page


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call)
            and getattr(n.func, 'id', getattr(n.func, 'attr', '')) == name]


def _first_str(call: ast.Call) -> str:
    arg = call.args[0]
    assert isinstance(arg, ast.Constant) and isinstance(arg.value, str), ast.dump(arg)
    return arg.value


LAUNCH_FILES = sorted((REPO / 'launch').glob('*.launch.py'))


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_arguments_namespace_sim_time_params_file(path):
    tree = ast.parse(path.read_text(encoding='utf-8'))
    declared = {_first_str(c) for c in _calls(tree, 'DeclareLaunchArgument')}
    used = {_first_str(c) for c in _calls(tree, 'LaunchConfiguration')}
    assert {'namespace', 'use_sim_time', 'params_file'} <= declared, declared
    assert used == declared, (used, declared)          # none declared in vain, none undeclared
    nodes = _calls(tree, 'Node')
    assert nodes
    for node in nodes:
        keywords = {k.arg: k.value for k in node.keywords}
        namespace = keywords.get('namespace')
        assert namespace is not None and 'namespace' in ast.unparse(namespace), ast.dump(node)
        assert 'params_file' in ast.unparse(keywords['parameters'])


def test_no_comment_names_a_launch_file_that_does_not_exist():
    names = {p.name for p in LAUNCH_FILES}
    for page in [REPO / 'package.xml', REPO / 'README.md', *(REPO / 'docs').glob('*.md'),
                 *(REPO / 'train_dynamics').rglob('*.py'), *LAUNCH_FILES]:
        for mentioned in re.findall(r'[\w-]+\.launch\.py', page.read_text(encoding='utf-8')):
            assert mentioned in names, f'{page.relative_to(REPO)} names {mentioned}'
