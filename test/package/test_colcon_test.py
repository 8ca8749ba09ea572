"""
``colcon test`` runs the package's pytest suite and fails when a test fails.

A fresh colcon workspace holds the package with a stand-in ``test/`` of two small tests (the
real suite takes minutes); ``colcon test --return-code-on-test-failure`` must run them (the
JUnit result counts them) and exit 0, then exit non-zero once one of them fails.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGE_FILES = ['package.xml', 'setup.py', 'setup.cfg', 'resource', 'train_dynamics']
_IGNORE = shutil.ignore_patterns('__pycache__', '*.pyc', '*.nbi', '*.nbc', '*.egg-info',
                                 '_prebuilt')


def _colcon(ws: Path, env: dict, *args: str) -> subprocess.CompletedProcess:
    colcon = Path(sys.executable).parent / 'colcon'
    return subprocess.run([str(colcon), *args], cwd=ws, env=env, capture_output=True,
                          text=True, timeout=600)


def test_colcon_test_runs_the_tests_and_fails_when_one_fails(tmp_path):
    if shutil.which('bash') is None:
        pytest.skip('colcon needs bash for its setup files')
    src = tmp_path / 'src' / 'train_dynamics'
    src.mkdir(parents=True)
    for name in PACKAGE_FILES:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=_IGNORE)
        else:
            shutil.copy2(path, src / name)
    (src / 'test').mkdir()
    (src / 'test' / 'test_stand_in.py').write_text(
        'def test_one():\n    assert 1 + 1 == 2\n\n\n'
        'def test_two():\n    import train_dynamics.topics\n'
        "    assert train_dynamics.topics.NODE_NAME == 'train_dynamics'\n")
    env = dict(os.environ, TRAIN_DYNAMICS_PREBUILD='0')
    env['PATH'] = f'{Path(sys.executable).parent}{os.pathsep}{env.get("PATH", "")}'
    for name in ('PYTHONPATH', 'AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH'):
        env.pop(name, None)
    build = _colcon(tmp_path, env, 'build', '--base-paths', 'src')
    assert build.returncode == 0, build.stdout + build.stderr

    run = _colcon(tmp_path, env, 'test', '--base-paths', 'src',
                  '--return-code-on-test-failure')
    assert run.returncode == 0, run.stdout + run.stderr
    result = ET.parse(tmp_path / 'build' / 'train_dynamics' / 'pytest.xml').getroot()
    suite = result if result.tag == 'testsuite' else result.find('testsuite')
    assert int(suite.get('tests')) == 2 and int(suite.get('failures')) == 0

    (src / 'test' / 'test_stand_in.py').write_text('def test_fails():\n    assert False\n')
    run = _colcon(tmp_path, env, 'test', '--base-paths', 'src',
                  '--return-code-on-test-failure')
    assert run.returncode != 0, run.stdout + run.stderr
