"""
Start-up of the compiled kernel: a run loads no more than it uses.

numba's array functions probe for scipy's BLAS when they are imported (on the first kernel
call), which imports ``scipy.linalg`` (0.10-0.12 s CPU of a 0.6-0.9 s start); the kernels use
no BLAS, so ``compiler`` imports them with the probe failing
(:func:`train_dynamics.physics.kernel.compiler._skip_blas_probe`). Each case runs a fresh
interpreter: what a start imports is decided once per process.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

from train_dynamics.physics.kernel import compiler as _jit

needs_numba = pytest.mark.skipif(not _jit.HAVE_NUMBA, reason='numba is not installed')

REPO = Path(__file__).resolve().parents[2]

RUN = """
import sys
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.train import TrainSimulator
sim = TrainSimulator(SimConfig.from_dict({'num_coaches': 3}))
sim.set_head_pipe_pressure(0.0)
sim.advance_to(0.1)
print(sim.steps, 'scipy.linalg' in sys.modules)
"""

DOT_AFTER = """
import numpy as np
import numba
from train_dynamics.physics.kernel import compiler
import numba.np.arraymath
assert 'scipy.linalg' not in __import__('sys').modules


@numba.njit
def dot(a, b):
    return np.dot(a, b)


print(dot(np.arange(3.0), np.arange(3.0)))
"""


def _python(code: str) -> str:
    env = {**os.environ, 'PYTHONPATH': str(REPO) + os.pathsep + os.environ.get('PYTHONPATH', '')}
    out = subprocess.run([sys.executable, '-c', code], env=env, cwd=str(REPO),
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


@needs_numba
def test_a_run_of_the_kernel_does_not_import_scipy_linalg():
    steps, imported = _python(RUN)
    assert steps == '50'            # 0.1 s at the 2 ms step: the kernel ran
    assert imported == 'False'


@needs_numba
def test_blas_still_serves_np_dot_in_other_jitted_code():
    assert _python(DOT_AFTER) == ['5.0']      # 0*0 + 1*1 + 2*2
