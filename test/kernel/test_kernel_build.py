"""
What a build compiles, and what a user waiting for a compilation sees.

- ``TRAIN_DYNAMICS_PREBUILD`` (``setup.py build`` / ``develop``, i.e. ``colcon build``):
  unset means the default configuration's kernels only (``paper``), ``all`` every group,
  ``0`` none; an unknown group is a one-line error;
- every kernel function compiled is reported as it ends (name, seconds), numba's own
  implementations of numpy functions are not.
"""
from __future__ import annotations

import argparse
import re

import pytest

from train_dynamics.cli import prebuild
from train_dynamics.physics.kernel import compiler


def test_build_compiles_the_default_group_unless_told_otherwise():
    assert prebuild.build_groups(None) == 'paper'          # was: every group (minutes more)
    assert prebuild.build_groups('1') == 'paper'
    assert prebuild.build_groups('all') == ','.join(prebuild.VARIANTS)
    assert prebuild.build_groups('paper,pneumatic') == 'paper,pneumatic'
    assert prebuild.build_groups('0') == prebuild.build_groups('none') == ''
    with pytest.raises(argparse.ArgumentTypeError, match='unknown variant group'):
        prebuild.build_groups('fast')


def test_build_with_prebuild_off_compiles_nothing(monkeypatch, capsys):
    monkeypatch.setenv(prebuild.PREBUILD_ENV, '0')
    warmed = []
    monkeypatch.setattr(prebuild, 'warm', warmed.append)
    assert prebuild.main(['--build']) == 0
    assert warmed == []
    assert 'first start compiles' in capsys.readouterr().out


@pytest.mark.skipif(not compiler.HAVE_NUMBA, reason='numba not installed')
def test_each_compiled_kernel_function_is_reported():
    import numba
    from numba.core import event

    def probe_kernel(x):
        return x * 2.0 + 1.0

    probe_kernel.__module__ = 'train_dynamics.physics.kernel.probe'
    lines: list[str] = []
    saved = compiler._state.pop('progress', None)
    if saved is not None:
        event.unregister('numba:compile', saved)
    try:
        assert compiler.report_compilation(lines.append)
        assert numba.njit(probe_kernel)(1.0) == 3.0        # compiled now (no cache)
        numba.njit(lambda x: x + 1)(1)                      # not ours: not reported
    finally:
        event.unregister('numba:compile', compiler._state.pop('progress'))
        if saved is not None:
            compiler._state['progress'] = saved
            event.register('numba:compile', saved)
    assert lines[0].startswith('train_dynamics: compiling the numba kernels this run needs')
    assert len(lines) == 2, lines
    assert re.fullmatch(r'train_dynamics: compiled probe\.\S*probe_kernel '
                        r'\(\d+\.\d s; 1 so far\)', lines[1]), lines[1]
