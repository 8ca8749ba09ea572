"""
A property-based fuzz (Hypothesis) over consist files, well-formed and hostile.

Entries of library and file-defined types with counts and field overrides drawn inside, at and
beyond the bounds; hostile ones: odd types (lists, mappings, huge integers, NaN/inf),
unknown fields and keys, huge counts, nested lists, alias bombs. Every file the configuration
accepts runs 1 s offline to finite outputs (or a reported fault); every file it refuses gives
one line ``train-dynamics: error: ...`` and exit 2 through the command line. None takes more
than a few seconds or much memory.
"""
from __future__ import annotations

import math
import time
import tracemalloc

from fuzz_helpers import run_one_second
from hypothesis import event, given, HealthCheck, settings, strategies as st
import pytest

from train_dynamics.cli import offline as cli
from train_dynamics.physics.config import ConfigError, SimConfig, VEHICLE_PARAMETERS
from train_dynamics.physics.config.consist import library_types
import yaml

LIBRARY = sorted(library_types())
#: numeric vehicle fields (brake_regime is a choice)
NUMERIC = [f for f, s in VEHICLE_PARAMETERS.items() if s.kind == 'double']
#: an alias bomb (~387 million strings expanded): its text, used as a field value
BOMB = ('[&a [l, l, l, l, l, l, l, l, l], '
        + ', '.join(f'&{chr(98 + k)} [{", ".join([f"*{chr(97 + k)}"] * 9)}]' for k in range(8))
        + ']')
ODD = st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1.0, 0.0, 10 ** 400, '12',
                       'x' * 5000, [1.0, 2.0], {'a': 1}, None, True])


def _field_value(field: str):
    spec = VEHICLE_PARAMETERS[field]
    if field == 'brake_regime':
        return st.sampled_from(['P', 'G', 'X', 'p'])
    edges = [v for v in (spec.low, spec.high, spec.default) if v is not None]
    near = [e * f for e in edges for f in (0.5, 1.0, 1.000001, 2.0)]
    return st.one_of(st.sampled_from(near), st.floats(spec.low, spec.high, allow_nan=False),
                     ODD)


OVERRIDES = st.dictionaries(st.sampled_from(NUMERIC + ['brake_regime']), st.none(),
                            max_size=3).flatmap(
    lambda d: st.fixed_dictionaries({k: _field_value(k) for k in d}))

ENTRY = st.one_of(
    st.builds(lambda t, c, o: {'type': t, **({'count': c} if c is not None else {}), **o},
              st.sampled_from(LIBRARY + ['my_wagon']),
              st.one_of(st.none(), st.integers(1, 3),
                        st.sampled_from([0, -1, 10 ** 8, 10 ** 30, 2.5, 'many', True])),
              OVERRIDES),
    st.builds(lambda t: {'type': t}, ODD),                        # an odd type name
    st.builds(lambda k: {'type': 'paper_coach', k: 1.0},          # an unknown field
              st.sampled_from(['mas', 'count ', 'lenght', ''])),
    ODD,                                                           # no mapping at all
)


def _inside(field: str):
    spec = VEHICLE_PARAMETERS[field]
    if field == 'brake_regime':
        return st.just('P')
    low = spec.low if not spec.low_exclusive else spec.low + max(abs(spec.low) * 1e-9, 1e-9)
    return st.floats(low, spec.high, allow_nan=False)


#: well-formed entries: library types, small counts, overrides within the bounds
WELL_ENTRY = st.builds(
    lambda t, c, o: {'type': t, 'count': c, **o}, st.sampled_from(LIBRARY),
    st.integers(1, 3),
    st.dictionaries(st.sampled_from(NUMERIC), st.none(), max_size=3).flatmap(
        lambda d: st.fixed_dictionaries({k: _inside(k) for k in d})))

HOSTILE = st.fixed_dictionaries(
    {'vehicles': st.one_of(st.lists(ENTRY, min_size=1, max_size=4), ODD)},
    optional={'vehicle_types': st.one_of(
                  st.fixed_dictionaries({'my_wagon': OVERRIDES}), ODD),
              'trains': st.just([1])})
DOC = st.one_of(st.fixed_dictionaries({'vehicles': st.lists(WELL_ENTRY, min_size=2,
                                                            max_size=4)}), HOSTILE)


def _text(doc: dict, bomb_at: int | None) -> str:
    """Return the YAML of ``doc``; with ``bomb_at``, an alias bomb as a field of that entry."""
    text = yaml.safe_dump(doc, default_flow_style=True, width=10 ** 9)
    if bomb_at is None or not isinstance(doc.get('vehicles'), list):
        return text
    entries = doc['vehicles']
    k = bomb_at % len(entries)
    if not isinstance(entries[k], dict):
        return text
    entries = list(entries)
    entries[k] = {**entries[k], 'mass': '@BOMB@'}
    return yaml.safe_dump({**doc, 'vehicles': entries}, default_flow_style=True,
                          width=10 ** 9).replace("'@BOMB@'", BOMB)


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(doc=DOC, bomb_at=st.one_of(st.none(), st.none(), st.integers(0, 3)))
def test_consist_files_run_one_second_or_are_refused_in_one_line(
        doc, bomb_at, tmp_path, capsys):
    path = tmp_path / 'consist.yaml'
    path.write_text(_text(doc, bomb_at))
    tracemalloc.start()
    t0 = time.process_time()         # CPU s: the work, not the machine's load
    try:
        cfg = SimConfig.from_dict({'consist_file': str(path), 'integration_step': 0.005,
                                   'publish_rate': 20.0})
        error = None
    except ConfigError as exc:
        error = str(exc)
    finally:
        took, peak = time.process_time() - t0, tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert took < 3.0 and peak < 200e6, (took, peak)
    if error is not None:
        event('rejected')
        assert '\n' not in error and len(error) < 2000
        params = tmp_path / 'p.yaml'
        params.write_text('train_dynamics:\n  ros__parameters:\n'
                          f'    consist_file: {path}\n')
        t0 = time.process_time()
        code = cli.main(['simulate', '--params', str(params), '--duration', '1', '--output',
                         str(tmp_path / 'never'), '-q'])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith('train-dynamics: error: '), err
        assert time.process_time() - t0 < 10.0 and not (tmp_path / 'never').exists()
        return
    event('accepted')
    assert cfg.n_coaches <= 12
    run_one_second(cfg)


@pytest.mark.parametrize('count', [10 ** 8, 10 ** 30])
def test_huge_counts_are_refused_quickly(tmp_path, count):
    path = tmp_path / 'c.yaml'
    path.write_text(f'vehicles: [{{type: paper_coach, count: {count}}}]\n')
    t0 = time.process_time()
    with pytest.raises(ConfigError, match='count'):
        SimConfig.from_dict({'consist_file': str(path)})
    assert time.process_time() - t0 < 1.0
