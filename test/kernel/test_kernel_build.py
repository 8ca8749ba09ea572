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


def test_the_large_step_pieces_compile_apart_from_the_driver():
    # inlined (numba's inline='always'), they made the driver one function whose compilation
    # took 85-90 % of the default group's (minutes on one core)
    from train_dynamics.physics.kernel import fixed_step
    names = [name for name, _, _, _ in prebuild.part_calls()]
    assert {'refine', 'active_set', 'wheelsets', 'first_call'} <= set(names)
    if not compiler.HAVE_NUMBA:
        return
    for name, _, function, _ in prebuild.part_calls():
        assert function.targetoptions['inline'] == 'never', name
    assert fixed_step.advance_chain.targetoptions['inline'] == 'never'


def test_the_parts_are_listed_with_the_types_the_driver_calls_them_with(monkeypatch):
    # a part listed with other types would compile twice: in parallel, then in the driver.
    # The driver's Python runs one step, every compiled function it calls replaced by a stub
    # that records its arguments (every option on: wheelsets, external forces, multirate).
    if not compiler.HAVE_NUMBA:
        pytest.skip('numba not installed')
    from numba import typeof
    from numba.core.dispatcher import Dispatcher
    from train_dynamics.physics.config import SimConfig
    from train_dynamics.physics.kernel import brakes, fixed_step, wheelset
    from train_dynamics.physics.kernel.layout import OPTION
    from train_dynamics.physics.train import TrainSimulator
    sim = TrainSimulator(SimConfig.from_dict({}))
    sim.iv[OPTION.WHEELS] = sim.iv[OPTION.EXT] = 1
    calls: dict = {}
    returns = {'scratch_size': 1, '_all_held': False, '_repeats_standstill': False,
               'fault_check': 0, 'make_tables': None}

    def stub(name, function):
        def record(*args):
            calls[function] = tuple(typeof(a) for a in args)
            return returns.get(name, 0.0)
        return record

    for module in (fixed_step, wheelset, brakes):
        for name, value in list(vars(module).items()):
            if isinstance(value, Dispatcher) and name != 'advance_chain':
                monkeypatch.setattr(module, name, stub(name, value))
    fixed_step.advance_chain.py_func(1, sim.coach, sim.cpl, sim.sc, sim.iv, sim.fill,
                                     sim.rel, sim.ring, sim.ws, sim.gprof, sim.cprof,
                                     sim.aprof)
    monkeypatch.undo()
    for name, _, function, args in prebuild.part_calls():
        assert calls.get(function) == tuple(typeof(a) for a in args), name


def test_the_parts_are_shared_out_evenly():
    parts = {name: seconds for name, seconds, _, _ in prebuild.part_calls()}
    shares = prebuild.share_parts(2)
    assert sorted(sum(shares, [])) == sorted(parts)          # each part once
    loads = [sum(parts[name] for name in share) for share in shares]
    assert abs(loads[0] - loads[1]) <= max(parts.values()) / 2
    assert prebuild.share_parts(1) == [list(parts)]


def test_a_cold_build_compiles_the_parts_in_a_helper_process_too(monkeypatch, capsys):
    started, compiled, warmed = [], [], []

    class Helper:

        def __init__(self, cmd, **kwargs):
            started.append(cmd)

        def wait(self):
            return 0

    monkeypatch.setattr(prebuild.subprocess, 'Popen', Helper)
    monkeypatch.setattr(prebuild, 'compile_parts', compiled.append)
    monkeypatch.setattr(prebuild, 'warm', warmed.append)
    monkeypatch.setattr(prebuild, 'driver_cached', lambda: False)
    if not compiler.HAVE_NUMBA:
        pytest.skip('numba not installed')
    assert prebuild.main(['--variants', 'paper', '--jobs', '2']) == 0
    shares = prebuild.share_parts(2)
    assert compiled == [shares[0]]
    assert len(started) == 1 and started[0][-2:] == ['--parts', ','.join(shares[1])]
    assert warmed == [['paper']]
    assert 'in 2 processes' in capsys.readouterr().out
    # the driver already compiled (a warm cache): no helper process
    started.clear()
    monkeypatch.setattr(prebuild, 'driver_cached', lambda: True)
    assert prebuild.main(['--variants', 'paper', '--jobs', '2']) == 0
    assert started == []


def test_an_interrupted_build_stops_its_helper_process(monkeypatch):
    stopped = []

    class Helper:

        def __init__(self, cmd, **kwargs):
            pass

        def terminate(self):
            stopped.append('terminated')

        def wait(self):
            stopped.append('waited')

    def interrupted(names):
        raise KeyboardInterrupt

    monkeypatch.setattr(prebuild.subprocess, 'Popen', Helper)
    monkeypatch.setattr(prebuild, 'compile_parts', interrupted)
    with pytest.raises(KeyboardInterrupt):
        prebuild.compile_in_parallel(2)
    assert stopped == ['terminated', 'waited']
