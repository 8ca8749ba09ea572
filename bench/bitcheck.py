"""
Bit-for-bit check of the shipped scenarios across a refactor.

    python bench/bitcheck.py --write DIR     # before the change: record the reference bags
    python bench/bitcheck.py --check DIR     # after it: every message must be identical

Run from the root of the checkout under test (its ``train_dynamics`` is the one imported).

Each scenario runs through the offline command (``train-dynamics simulate``), exactly as a
user runs it; the check compares every message of every topic (topic, bag time, CDR bytes),
so a change of one bit in one sample is found and named. A topic added since the reference
was written is named, not counted as a difference: every topic of the reference must be
identical. Prints one line per scenario and exits 1 when any differs.
"""
from __future__ import annotations

import argparse
import hashlib
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile

from rosbags.highlevel import AnyReader

#: the checkout under test: the current directory (run it from the repository's root, e.g. a
#: git worktree, so that its own ``train_dynamics`` is imported)
REPO = Path.cwd()

#: the offline command, as its console script runs it
OFFLINE = 'import sys; from train_dynamics.cli.offline import main; sys.exit(main())'

#: (name, parameter file, duration [s])
SCENARIOS = (
    ('paper', 'config/paper_3coach.yaml', 60.0),
    ('paper_adaptive', 'config/paper_3coach_adaptive.yaml', 20.0),
    ('freight', 'config/freight_750m.yaml', 150.0),
    ('passenger', 'config/passenger_loco_12.yaml', 60.0),
    ('slack_runin', 'config/slack_runin.yaml', 40.0),
)


def digest(bag: Path) -> tuple[int, str, dict[str, str]]:
    """Count, overall hash and per-topic hash of every message (topic, time, raw bytes)."""
    total = hashlib.sha256()
    per: dict[str, hashlib._Hash] = {}
    n = 0
    with AnyReader([bag]) as reader:
        for conn, t, raw in reader.messages():
            key = conn.topic.lstrip('/')
            h = per.setdefault(key, hashlib.sha256())
            for sink in (h, total):
                sink.update(key.encode())
                sink.update(t.to_bytes(8, 'little', signed=True))
                sink.update(bytes(raw))
            n += 1
    return n, total.hexdigest(), {k: v.hexdigest() for k, v in sorted(per.items())}


def run(out: Path, params: str, duration: float) -> None:
    """One offline run into ``out`` (replaced)."""
    subprocess.run(['rm', '-rf', str(out)], check=True)
    cmd = [sys.executable, '-c', OFFLINE, 'simulate', '--params', str(REPO / params),
           '--duration', str(duration), '--output', str(out)]
    subprocess.run(cmd, check=True, cwd=REPO, stdout=subprocess.DEVNULL)


def main(argv: list[str] | None = None) -> int:
    """Write or check the reference digests."""
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument('--write', metavar='DIR', type=Path)
    g.add_argument('--check', metavar='DIR', type=Path)
    p.add_argument('--only', nargs='*', help='scenario names (default: all)')
    a = p.parse_args(argv)
    root = a.write or a.check
    root.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix='bitcheck-'))
    bad = 0
    for name, params, duration in SCENARIOS:
        if a.only and name not in a.only:
            continue
        bag = (root / 'ref_' if a.write else scratch) / name
        bag.parent.mkdir(exist_ok=True)
        run(bag, params, duration)
        n, total, per = digest(bag)
        ref = root / f'{name}.digest'
        if a.write:
            ref.write_text('\n'.join([f'{n} {total}'] + [f'{k} {v}' for k, v in per.items()])
                           + '\n')
            print(f'{name:15s} {n:7d} messages  {total[:16]}  written')
            continue
        want = dict(line.split() for line in ref.read_text().splitlines()[1:])
        changed = sorted(k for k in want if per.get(k) != want[k])
        added = sorted(k for k in per if k not in want)
        if not changed:
            more = f'; topics added since: {", ".join(added)}' if added else ''
            print(f'{name:15s} {n:7d} messages  identical{more}')
        else:
            bad += 1
            print(f'{name:15s} DIFFERS in {", ".join(changed)}')
    shutil.rmtree(scratch, ignore_errors=True)
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
