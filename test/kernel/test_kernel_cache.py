"""
The compiled-kernel cache: keyed by content, never stale, never fatal; the kernel is one folder.

``physics/kernel/compiler.py`` files every kernel under a digest of the folder's sources, so
every compiled function must live in ``physics/kernel/`` (checked here).

Each case runs a fresh interpreter on a copy of the package (``train_dynamics`` only) with a
small probe kernel added to ``physics/kernel/`` and an own ``TRAIN_DYNAMICS_CACHE_DIR``; the
probe prints its result and ``compiler.cache_stats()`` (signatures loaded from the cache /
compiled).
"""
from __future__ import annotations

import ast
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

from train_dynamics.physics.kernel import compiler as _jit

needs_numba = pytest.mark.skipif(not _jit.HAVE_NUMBA, reason='numba is not installed')

REPO = Path(__file__).resolve().parents[2]
KERNEL = REPO / 'train_dynamics' / 'physics' / 'kernel'
PROBE_KERNEL = """
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import STATE


@jit
def probe(x):
    return 2.0 * x + STATE.V
"""
PROBE = """
import ast
import json
import os
import tempfile
tempfile.tempdir = os.environ.get('PROBE_TMPDIR') or None   # the last fall-back folder
from train_dynamics.physics.kernel import compiler as _jit
from train_dynamics.physics.kernel._probe_kernel import probe
print(json.dumps({'value': probe(1.5), **_jit.cache_stats(), 'dir': _jit.kernel_cache_dir(),
                  'file': _jit.__file__}))
"""


def _copy(dest: Path) -> Path:
    """Copy the package to ``dest`` with the probe kernel; return the copy's kernel folder."""
    shutil.copytree(REPO / 'train_dynamics', dest / 'train_dynamics',
                    ignore=shutil.ignore_patterns('__pycache__', '_prebuilt'))
    physics = dest / 'train_dynamics' / 'physics' / 'kernel'
    (physics / '_probe_kernel.py').write_text(PROBE_KERNEL)
    return physics


def _run(root: Path, cache: Path, **env) -> dict:
    """Run the probe on the copy at ``root`` with the user cache ``cache``; return its report."""
    full = dict(os.environ, PYTHONPATH=str(root), TRAIN_DYNAMICS_CACHE_DIR=str(cache), **env)
    full.pop('NUMBA_DISABLE_JIT', None)
    out = subprocess.run([sys.executable, '-c', PROBE], cwd=root, env=full,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert Path(report['file']).is_relative_to(root), report['file']   # the copy ran
    return report


def _expected(physics: Path) -> float:
    layout = {}
    exec(compile((physics / 'layout.py').read_text(), 'layout.py', 'exec'), layout)
    return 3.0 + layout['STATE'].V


@needs_numba
def test_a_copy_elsewhere_loads_the_kernels_another_copy_compiled(tmp_path):
    cache = tmp_path / 'cache'
    first, second = _copy(tmp_path / 'a'), _copy(tmp_path / 'b' / 'deeper')
    (second / 'step.py').touch()               # a new mtime changes nothing
    a = _run(tmp_path / 'a', cache)
    assert (a['compiled'], a['loaded']) == (1, 0)
    b = _run(tmp_path / 'b' / 'deeper', cache)
    assert (b['compiled'], b['loaded']) == (0, 1)
    assert a['dir'] == b['dir'] and Path(a['dir']).parent == cache
    assert a['value'] == b['value'] == _expected(first)


@needs_numba
def test_a_change_in_any_kernel_source_compiles_again(tmp_path):
    """
    Check that an edit of a module the kernel takes a constant from is never served stale.

    The probe's own file is unchanged; ``layout.py`` swaps two coach rows so ``STATE.V``
    (frozen into the machine code) changes: the old code would return the old value.
    """
    cache = tmp_path / 'cache'
    physics = _copy(tmp_path / 'a')
    old = _run(tmp_path / 'a', cache)
    assert old['value'] == _expected(physics)
    layout = physics / 'layout.py'
    lines = layout.read_text().splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if line.strip().startswith("'X',"))
    j = next(k for k, line in enumerate(lines) if line.strip().startswith("'V',"))
    lines[i], lines[j] = lines[j], lines[i]
    layout.write_text(''.join(lines))
    new = _run(tmp_path / 'a', cache)
    assert (new['compiled'], new['loaded']) == (1, 0)
    assert new['dir'] != old['dir']
    assert new['value'] == _expected(physics) != old['value']
    again = _run(tmp_path / 'a', cache)
    assert (again['compiled'], again['loaded'], again['value']) == (0, 1, new['value'])


@needs_numba
def test_source_digest_covers_every_kernel_source(tmp_path):
    """The digest follows the folder: every .py in it, a new one, a removed one."""
    physics = _copy(tmp_path / 'a')
    with_probe = _jit.source_digest(str(physics))
    (physics / '_probe_kernel.py').unlink()
    base = _jit.source_digest(str(physics))
    assert base == _jit.source_digest(str(KERNEL)) != with_probe
    assert set(_jit.kernel_sources(str(physics))) == {p.name for p in KERNEL.glob('*.py')}
    for name in _jit.kernel_sources(str(physics)):
        path = physics / name
        original = path.read_bytes()
        path.write_bytes(original + b'\n')
        assert _jit.source_digest(str(physics)) != base, name
        path.write_bytes(original)
    assert _jit.source_digest(str(physics)) == base


@needs_numba
def test_no_writable_cache_compiles_in_memory(tmp_path):
    blocker = tmp_path / 'file'
    blocker.write_text('not a folder')
    kernel = _copy(tmp_path / 'a')
    for _ in range(2):
        rep = _run(tmp_path / 'a', blocker / 'cache', PROBE_TMPDIR=str(blocker / 'tmp'))
        assert (rep['compiled'], rep['loaded'], rep['dir']) == (1, 0, '')
        assert rep['value'] == _expected(kernel)


@needs_numba
def test_a_damaged_cache_file_is_a_miss_not_a_failure(tmp_path):
    cache = tmp_path / 'cache'
    _copy(tmp_path / 'a')
    first = _run(tmp_path / 'a', cache)
    data = list(Path(first['dir']).glob('_probe_kernel.probe-*.nbc'))
    assert len(data) == 1
    data[0].write_bytes(data[0].read_bytes()[:40])
    rep = _run(tmp_path / 'a', cache)
    assert (rep['compiled'], rep['loaded']) == (1, 0)
    assert rep['value'] == first['value']


@needs_numba
def test_prebuilt_kernels_are_read_before_the_user_cache(tmp_path):
    """What ``setup.py build`` leaves in ``physics/_prebuilt`` serves an empty user cache."""
    physics = _copy(tmp_path / 'a')
    warm = _run(tmp_path / 'a', tmp_path / 'build_cache')
    shutil.copytree(warm['dir'], physics / _jit.PREBUILT / Path(warm['dir']).name)
    empty = tmp_path / 'empty'
    rep = _run(tmp_path / 'a', empty)
    assert (rep['compiled'], rep['loaded']) == (0, 1)
    assert not any(p.is_file() for p in empty.rglob('*'))      # nothing written


def _is_jit(decorator) -> bool:
    target = decorator.func if isinstance(decorator, ast.Call) else decorator
    name = target.attr if isinstance(target, ast.Attribute) else getattr(target, 'id', '')
    return name in ('jit', 'njit', 'vectorize', 'guvectorize', 'cfunc')


def test_every_compiled_function_lives_in_the_kernel_folder():
    """
    Check that the digest's folder holds all compiled code, and that it depends on nothing else.

    The cache key covers the .py files of ``physics/kernel/`` only: a jitted function
    elsewhere (in the package, or in a benchmark or test that compiles through
    ``compiler.jit``), or a kernel module that takes a function or constant from outside the
    folder (numba inlines and freezes them), could run stale machine code after an edit. The
    one import allowed is the layout's from the parameter table: the per-vehicle rows declared
    there are part of the key (``compiler.table_kernel_rows``, checked in test_consist).
    """
    package = REPO / 'train_dynamics'
    outside, foreign = [], []
    scripts = [*(REPO / 'bench').rglob('*.py'), *(REPO / 'test').rglob('*.py')]
    for path in sorted([*package.rglob('*.py'), *scripts]):
        tree = ast.parse(path.read_text(encoding='utf-8'))
        in_kernel = path.parent == KERNEL
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if any(_is_jit(d) for d in node.decorator_list) and not in_kernel:
                    outside.append(f'{path.relative_to(REPO)}:{node.name}')
            elif in_kernel and isinstance(node, ast.ImportFrom) and node.module:
                mod = node.module
                if (path.name, mod) == ('layout.py', 'train_dynamics.physics.config.table'):
                    continue
                if mod.startswith('train_dynamics') and not mod.startswith(
                        'train_dynamics.physics.kernel'):
                    foreign.append(f'{path.name}: {mod}')
            elif in_kernel and isinstance(node, ast.Import):
                foreign += [f'{path.name}: {a.name}' for a in node.names
                            if a.name.startswith('train_dynamics')]
    assert not outside, f'jitted functions outside physics/kernel/: {outside}'
    assert not foreign, f'kernel modules importing outside the kernel: {foreign}'
    assert {'step.py', 'fixed_step.py', 'adaptive.py', 'standstill.py', 'layout.py',
            'couplers.py', 'brakes.py'} <= set(_jit.kernel_sources())
