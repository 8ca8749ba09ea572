"""`train-dynamics plot`: PNG figures from any bag holding couplers."""
from __future__ import annotations

from pathlib import Path
import zlib

import numpy as np
import pytest

from train_dynamics.cli import offline as cli
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.history import load_history, sign_changes_per_second
from train_dynamics.recording.messages import fluid_pressure, joint_state
from train_dynamics.recording.plots import png_size, SIZE_PX

COUPLER_FIGURES = {'coupler_displacement.png': 'single', 'coupler_velocity.png': 'single',
                   'coupler_force.png': 'single', 'couplers.png': 'stack'}


def check_png(path: Path, kind: str) -> None:
    """Check a complete PNG (signature, IHDR, IDAT, IEND, CRCs) of the expected pixel size."""
    data = path.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n'
    pos, chunks = 8, []
    while pos < len(data):
        length = int.from_bytes(data[pos:pos + 4], 'big')
        ctype = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        crc = int.from_bytes(data[pos + 8 + length:pos + 12 + length], 'big')
        assert zlib.crc32(ctype + body) == crc, ctype
        chunks.append(ctype)
        pos += 12 + length
    assert chunks[0] == b'IHDR' and chunks[-1] == b'IEND' and b'IDAT' in chunks
    assert png_size(path) == SIZE_PX[kind]


def synthetic_bag(path: Path, n_couplers: int, *, slash: str = '', namespace: str = '',
                  reset_at: int | None = None, coaches: bool = False) -> None:
    """Write a bag as `ros2 bag record` would (absolute names), 10 s at 50 Hz."""
    names = [f'coupler_{i}' for i in range(1, n_couplers + 1)]
    prefix = f'{slash}{namespace}/' if namespace else slash
    with BagRecorder(path) as rec:
        k_all = list(range(501))
        if reset_at is not None:            # a run of 2 s, then the simulator is reset
            k_all = list(range(101)) + list(range(501))
        for seq, k in enumerate(k_all):
            t = k * 0.02
            phase = np.arange(n_couplers) * 0.3
            y = -0.02 * np.exp(-t / 3) * np.cos(2 * t + phase)
            rec.write_msg(prefix + 'couplers', 10 ** 9 + seq * 20_000_000, joint_state(
                t, names, y, 0.04 * np.sin(2 * t + phase),
                2.8e6 * y))
            if coaches:
                v = 44.4 - 0.8 * t
                n = n_couplers + 1
                rec.write_msg(prefix + 'coaches', 10 ** 9 + seq * 20_000_000, joint_state(
                    t, [f'coach_{i}' for i in range(1, n + 1)], [v * t] * n, [v] * n,
                    [44000.0] * n))


def test_plot_of_a_simulated_bag(tmp_path):
    params = tmp_path / 'p.yaml'
    params.write_text('train_dynamics:\n  ros__parameters:\n    num_coaches: 3\n'
                      'brake_valve:\n  ros__parameters:\n    schedule: ["0.5:emergency"]\n')
    assert cli.main(['simulate', '--params', str(params), '--duration', '4.0', '--output',
                     str(tmp_path / 'run'), '-q']) == 0
    assert cli.main(['plot', str(tmp_path / 'run'), '--output', str(tmp_path / 'fig'), '-q']) == 0
    files = {p.name for p in (tmp_path / 'fig').iterdir()}
    assert files == set(COUPLER_FIGURES) | {'coaches.png'}
    for name, kind in COUPLER_FIGURES.items():
        check_png(tmp_path / 'fig' / name, kind)
    check_png(tmp_path / 'fig' / 'coaches.png', 'coaches')
    # the history behind the figures is the bag's (mm, kN conversions happen only in drawing)
    hist = load_history(tmp_path / 'run')
    assert hist.couplers.names == ['coupler_1', 'coupler_2']
    assert len(hist.couplers) == 401 and hist.couplers.t[-1] == pytest.approx(4.0)
    assert hist.cylinders is not None and hist.head_pressure is not None
    assert hist.head_pressure[1][0] == pytest.approx(500000.0)       # gauge
    assert np.nanmin(hist.couplers.effort) < 0.0                     # buffers compressed


def test_plot_of_a_recorded_bag_many_couplers_namespace_and_reset(tmp_path, capsys):
    synthetic_bag(tmp_path / 'rec', 14, slash='/', namespace='train1', reset_at=100)
    assert cli.main(['plot', str(tmp_path / 'rec'), '--namespace', 'train1', '--output',
                     str(tmp_path / 'fig')]) == 0
    listed = capsys.readouterr().out.split()
    assert sorted(Path(p).name for p in listed) == sorted(COUPLER_FIGURES)
    for name, kind in COUPLER_FIGURES.items():
        check_png(tmp_path / 'fig' / name, kind)
    hist = load_history(tmp_path / 'rec', namespace='/train1')
    assert hist.couplers.names[:3] == ['coupler_1', 'coupler_2', 'coupler_3']   # natural order
    assert hist.couplers.names[-1] == 'coupler_14'
    assert len(hist.couplers) == 501                  # only the run after the reset
    assert any('backwards' in note for note in hist.notes)


def test_plot_errors(tmp_path, capsys):
    with BagRecorder(tmp_path / 'nocouplers') as rec:
        rec.write_msg('brake_pipe/pressure', 0, fluid_pressure(0.0, 6e5))
    for bag, expect in [(tmp_path / 'nocouplers', 'no couplers topic'),
                        (tmp_path / 'missing', 'bag not found')]:
        capsys.readouterr()
        assert cli.main(['plot', str(bag), '--output', str(tmp_path / 'fig')]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith('train-dynamics: error: ') and expect in err[0]
    assert not (tmp_path / 'fig').exists()


def test_sign_changes_per_second():
    t = np.linspace(0.0, 2.0, 201)
    v = np.stack([np.sin(2 * np.pi * t), np.where(np.arange(201) % 2, 1e-9, -1e-9),
                  np.zeros(201)], axis=1)
    rate = sign_changes_per_second(t, v, tol=0.0)
    assert rate[0] == pytest.approx(1.5)        # sin(2 pi t), t in (0, 2]: zeros at 0.5, 1, 1.5
    assert rate[1] == pytest.approx(100.0)      # flips every sample: chattering
    assert rate[2] == 0.0
