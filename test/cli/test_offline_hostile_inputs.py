"""
The offline command's exit statuses and input bags under hostile input: what is refused, how.

A list a reviewer can read:

- a configuration the simulator refuses when it is built (a friction material without a force
  level, a braked mass the brake cannot deliver) is exit 2 with one line ``<file>: invalid
  parameters: ...`` in ``simulate`` and ``compare`` (as ``sim_node``'s exit 2), nothing written
  (was: exit 1, ``ConfigError:`` / ``ValueError:``); a sweep whose every case has invalid
  parameters is exit 2 too (a sweep with some failing cases stays exit 1 / 0);
- a ``ConfigError`` from anywhere in a command is exit 2, one line;
- an input bag carrying only ``brake_ep/command`` drives an EP train (``pipe_head``: the pipe
  stays at ``pipe_nominal_pressure``, with a warning) (was: refused, "no usable input topic");
  a bag with nothing the run can use is still refused, exit 2;
- a full disk while ``simulate`` finishes its bag: exit 1, the recorder's one-line wording
  (what the bag holds of what was recorded), no ``.staging`` and no partial folder left.
"""
from __future__ import annotations

import errno
from pathlib import Path

import pytest

from train_dynamics.cli import offline, simulate
from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.recording.messages import typestore

ROOT = Path(__file__).resolve().parents[2]
FLOAT64 = 'std_msgs/msg/Float64'

#: parameters no simulator can be built of (refused when the file is read) -> words of the
#: reason
UNRUNNABLE = {
    'material without a force level': ('friction_material: cast_iron',
                                       'friction_material cast_iron needs its force level'),
    'braked mass beyond the brake': ('friction_material: cast_iron\n    braked_mass_p: 1.0e6',
                                     'shorter than the response time of the brake allows'),
}


def params_with(tmp_path: Path, extra: str, name: str = 'p.yaml',
                base: str = 'paper_3coach.yaml') -> Path:
    """Return a copy of a shipped parameter file with ``extra`` lines in the node section."""
    text = (ROOT / 'config' / base).read_text()
    marker = '  ros__parameters:\n'
    at = text.index(marker) + len(marker)
    path = tmp_path / name
    path.write_text(text[:at] + f'    {extra}\n' + text[at:])
    return path


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    lines = [ln for ln in err if ln.startswith('train-dynamics: error:')]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize('case', sorted(UNRUNNABLE))
@pytest.mark.parametrize('command', ['simulate', 'compare'])
def test_a_configuration_the_simulator_refuses_is_exit_2_in_one_line(tmp_path, capsys,
                                                                     command, case):
    extra, words = UNRUNNABLE[case]
    params = params_with(tmp_path, extra)
    out = tmp_path / 'deep' / 'out'
    code = offline.main([command, '--params', str(params), '--duration', '0.5', '--output',
                         str(out), '-q'])
    line = one_error_line(capsys)
    assert code == 2, line
    assert line.startswith(f'train-dynamics: error: {params}: '), line
    assert words in line
    assert not (tmp_path / 'deep').exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['p.yaml']


def test_a_sweep_of_invalid_cases_only_is_exit_2(tmp_path, capsys):
    # a base that runs, every case beyond what its brake can do
    params = params_with(tmp_path, 'friction_material: cast_iron\n    braked_mass_p: 40000.0')
    sweep = tmp_path / 'sweep.yaml'
    sweep.write_text('duration: 0.2\ngrid:\n  braked_mass_p: [9.0e5, 1.0e6]\n')
    code = offline.main(['sweep', '--params', str(params), '--sweep', str(sweep), '--output',
                         str(tmp_path / 'out'), '--workers', '1', '-q'])
    line = one_error_line(capsys)
    assert code == 2, line                               # was 1
    assert 'every case failed (2), the first: invalid parameters: ' in line, line


def test_a_config_error_from_anywhere_is_exit_2(tmp_path, capsys, monkeypatch):
    from train_dynamics.cli import report
    from train_dynamics.physics.config import ConfigError

    def refuse(*args, **kwargs):
        raise ConfigError('coupler_force_limit: must be >= 0')

    monkeypatch.setattr(report, 'read_run', refuse)
    bag = tmp_path / 'bag'
    BagRecorder(bag).close()
    code = offline.main(['report', str(bag), '--output', str(tmp_path / 'r'), '-q'])
    line = one_error_line(capsys)
    assert code == 2, line                               # was 1
    assert line == ('train-dynamics: error: invalid parameters: coupler_force_limit: must be '
                    '>= 0')


def command_bag(path: Path, topic: str, values: list[tuple[float, float]]) -> Path:
    types = typestore()
    with BagRecorder(path) as rec:
        rec.add_topic(topic, FLOAT64)
        for t, c in values:
            rec.write(topic, int(t * 1e9), types.serialize_cdr(types.types[FLOAT64](data=c),
                                                               FLOAT64))
    return path


def test_an_ep_command_bag_alone_drives_an_ep_train(tmp_path, capsys):
    bag = command_bag(tmp_path / 'ep', 'brake_ep/command', [(0.0, 0.0), (0.5, 1.0)])
    out = tmp_path / 'out'
    code = offline.main(['simulate', '--params', str(ROOT / 'config' / 'passenger_ep_16.yaml'),
                         '--input', str(bag), '--duration', '3', '--output', str(out), '-q'])
    err = capsys.readouterr().err
    assert code == 0, err                                # was 2: "no usable input topic"
    assert 'no brake_pipe/pressure input: the brake pipe stays at pipe_nominal_pressure' in err
    commands = [(t, m.data) for _, t, m in read_topics(out, ['brake_ep/command'])]
    assert commands == [(0, 0.0), (500_000_000, 1.0)]
    cylinders = [m for _, _, m in read_topics(out, ['brake_cylinders'])]
    assert max(cylinders[0].position) == 0.0             # released: the command was 0
    assert min(cylinders[-1].effort) > 4.9e5            # the pipe stayed charged (gauge Pa)
    assert min(cylinders[-1].position) > 3.0e5          # the EP command applied the brakes


def test_a_bag_with_nothing_the_run_can_use_is_refused(tmp_path, capsys):
    # an EP command is no input for a train without EP
    bag = command_bag(tmp_path / 'ep', 'brake_ep/command', [(0.0, 1.0)])
    code = offline.main(['simulate', '--params', str(ROOT / 'config' / 'paper_3coach.yaml'),
                         '--input', str(bag), '--duration', '1', '--output',
                         str(tmp_path / 'out'), '-q'])
    line = one_error_line(capsys)
    assert code == 2, line
    assert 'no usable input topic for brake_input pipe_head' in line
    assert not (tmp_path / 'out').exists()


def test_a_full_disk_at_the_end_of_simulate_leaves_no_staging(tmp_path, capsys, monkeypatch):
    class FullDisk(BagRecorder):

        def _finish_segment(self) -> None:
            raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(simulate, 'BagRecorder', FullDisk)
    out = tmp_path / 'out'
    code = offline.main(['simulate', '--params', str(ROOT / 'config' / 'paper_3coach.yaml'),
                         '--duration', '0.5', '--output', str(out), '-q'])
    line = one_error_line(capsys)
    assert code == 1, line
    assert f'recording to {out} failed (No space left on device at t = 0.500 s): the bag ' \
        'holds 0 of the ' in line and 'free some space' in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ['out']   # no partial folder
    assert sorted(p.name for p in out.iterdir()) == ['metadata.yaml']   # no .staging
    info = bag_info(out)
    assert info.message_count == 0 and 'No space left' in info.custom_data['incomplete']
