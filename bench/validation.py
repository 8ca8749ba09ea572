"""
Validation of the brakes against published results: ``python bench/validation.py``.

Runs every case of :mod:`train_dynamics.physics.validation` with the simulator
(``TrainSimulator``, the model the node and the offline command run) and writes
``docs/validation.md``: for each case its published source (paper, table or figure, page),
the inputs as given, how they map onto this package's fields, and published against ours
with the difference. ``--quick`` runs the cheap subset
the tests assert (``QUICK``); ``--output -`` prints the document instead of writing it.

The sources of every case (paper, table or figure, page) are cited in
:mod:`train_dynamics.physics.validation`'s docstring and printed in the document.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

# the cases live in the package (the tests run them too)
from train_dynamics.physics.validation import (emergency_cases, g_regime_cases,  # noqa: E402
                                               minden_cases, model_cases, QUICK, Row,
                                               shunting_cases, slip_cases)


# -- the document -------------------------------------------------------------------------------

def table(rows: list[Row], reference: bool = False) -> str:
    """Return a markdown table of ``rows``."""
    head = '| case | published [m] | ours [m] | difference |'
    rule = '| --- | ---: | ---: | ---: |'
    if reference:
        head += ' published model [m] |'
        rule += ' ---: |'
    head += ' note |'
    rule += ' --- |'
    out = [head, rule]
    for r in rows:
        line = f'| {r.case} | {r.published:.1f} | {r.ours:.1f} | {r.diff:+.1f} % |'
        if reference:
            line += f' {r.reference:.1f} |' if not math.isnan(r.reference) else ' |'
        out.append(line + f' {r.note} |')
    return '\n'.join(out)


def document() -> str:
    """Run every case; return docs/validation.md."""
    sections = [
        ('Minden relation, P (braked weight -> stopping distance)', minden_cases(), False,
         minden_cases.__doc__),
        ('Minden relation, P, disc pads', minden_cases((70, 110, 150), (120.0, 80.0), 'disc'),
         False, minden_cases.__doc__),
        ('UIC 544-1 G/P rule (equal braked weights)', g_regime_cases(), False,
         g_regime_cases.__doc__),
        ('Slip tests of an Eanos wagon [C&O] table 5', slip_cases(), True, slip_cases.__doc__),
        ('Shunting cases of [Pfaff]', shunting_cases(), True, shunting_cases.__doc__),
        ('Emergency stops from 30 km/h [C&O] table 7', emergency_cases(), True,
         emergency_cases.__doc__),
        ('The two brake models on [C&O] table 7', model_cases(), False, model_cases.__doc__),
    ]
    parts = [HEADER]
    for title, rows, reference, doc in sections:
        parts.append(f'## {title}\n\n{_dedent(doc)}\n\n{table(rows, reference)}\n')
    parts.append(FOOTER)
    return '\n'.join(parts)


def _dedent(doc: str) -> str:
    lines = [ln.strip() for ln in (doc or '').strip().splitlines()]
    return '\n'.join(lines)


HEADER = """# Validation: stopping distances against published results

Produced by `python bench/validation.py` (the simulator's model, `TrainSimulator`, in the
empirical brake model; every case an emergency at t = 0 on the level; the cases are
`train_dynamics/physics/validation.py`). Sources (the module docstring of
`bench/validation.py` gives them in full):

- [Minden]: the Minden formula, s = 3.85 v0^2 / (6.1 (1 + lambda / 10)) (Wende,
  Fahrdynamik des Schienenverkehrs, 2003, ch. 8), on which UIC 544-1 braked weights of P
  trains were set.
- [C&O]: Cantone & Ottati, The Open Transportation Journal 12 (2018), tables 5 and 7, as
  quoted with their inputs by [Pfaff].
- [Pfaff]: Pfaff et al., "Braking curves in low-speed on-sight operation", code and results
  in github.com/RailProfAC/ShuntingBrakingCurves (Code.ipynb); "published model" below is
  that model written anew from its stated equations
  (`train_dynamics/physics/pfaff_reference.py`), which reproduces the notebook's printed
  figures.

Difference: (ours - published) / published. Target: within 5 % where the source gives the
inputs; where not, the note says where the gap comes from.
"""

FOOTER = """## Where the gaps come from

- **Minden, P.** The braked weight sets the force so that the stop from 120 km/h is the
  formula's: disc pads (nearly constant mu) then follow the formula within 3 % at every
  speed; cast iron's mu rises steeply at low speed (2.2 times from 100 to 10 km/h) and
  with falling block force (so during the filling), so from below 120 km/h it stops 6-12 %
  shorter than the formula's v0^2 law, and 1-2 % shorter at 120 km/h (the filling). The
  formula is an average of P trains of all materials; a cast-iron vehicle's label is set
  at its top speed.
- **G/P rule.** The published figure here is the Minden P distance plus v0 times the
  difference of the response times; the exact distance with a gradual filling is shorter by
  a (M1,G - M1,P) (the fillings' spread, 12-17 m from 100 km/h:
  `test/physics/test_braked_weight.py`): ours 1.2-2.1 % short, on K blocks (nearly constant mu). On
  cast iron G stops shorter still: its mu is higher under the low block forces of the slow
  G filling (Karwatzki's force term), so the G filling costs less than v0 Delta t_e.
- **Slip tests.** [Pfaff] calibrated its rigging ratio on the 100 km/h tests; ours, with the
  same inputs, is within 1 % there and 4.3 % short from 120 km/h (the published model 4.6 %
  short): the K-block law's speed dependence.
- **[Pfaff]'s locomotive.** Its code adds the locomotive's full braking force a second time
  in the velocity update ("published model" column; the notes give the same model with the
  force counted once). Against that corrected model ours is within 1-4 % (0.8-3.4 %);
  against the printed figures the cases with a locomotive are 5-23 % longer, nearly all of it
  that error (the rest: our couplers and the wagons' slack, the one-mass model has none).
- **[C&O] table 7.** The published stops are cast-iron P10 and LL results. With each law
  calibrated on the same 100 km/h slip test: the library's cast_iron (Karwatzki) stops
  11-18 % SHORT from 30 km/h (its mu rises too much at low speed for these wagons), the
  library's composite_ll (a representative mean curve, a guess) 17-27 % LONG (it hardly
  rises), [Pfaff]'s K-block law in between (5-23 % long; within 1-3.3 % of [Pfaff]'s
  corrected model). The published P10 / LL spread itself is 4-10 %. What is not
  validated: a block law's low-speed branch; the published table gives no block curves,
  so no law here is fitted to it (fitting the LL curve to table 7 and checking it on
  table 7 would be circular).
- **The two brake models, GP and LL.** From 30 km/h a G train stops within its filling
  time, so the stop follows the filling's first seconds. Both models now run every brake
  position, each vehicle on its own regime (the empirical model's per-vehicle tables). The
  empirical G table (the measured P curve stretched six times, config/table.py) fills the
  first wagon to 30 % at 4 s and 59 % at 10 s; the pneumatic G distributor, with the
  first stage UIC 540 / EN 15355 ask of a distributor (`inshot_pressure` 0.4 bar, the
  default, the low end of the 0.4-0.7 bar of KE-type distributors; its chokes calibrated
  with it to 4 s and 24 s), to 25 % and 48 %. The two models agree within 1-3 %: P 46.5 /
  47.7 m, GP 48.2 / 49.2 m, LL 54.2 / 54.8 m, G 80.6 / 82.0 m (empirical / pneumatic).
  Without the first stage the pneumatic G wagons fill to 15 % and 38 % and the G train
  stops 22 % longer (the rows "no first stage"; with the chokes calibrated without it, the
  former default, 96.1 m). Against the published stops both models carry the block law's
  gap (cast iron calibrated at 100 km/h: 7-18 % short, see above), nearly the same in P,
  GP and LL (15-18 %): the brake positions add no gap of their own.
- Propagation: [Pfaff] stretches each wagon's filling time by the brake wave's arrival and
  so do these cases (the fillings are inputs); the simulator's own wave (250 m/s, empirical
  brake) is used in the Minden and G/P cases only.
"""


def main(argv=None) -> int:
    """Run the cases; write (or print) the document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--output', default=str(ROOT / 'docs' / 'validation.md'),
                        help="where to write the document ('-': print it)")
    parser.add_argument('--quick', action='store_true', help='run the cheap subset only')
    args = parser.parse_args(argv)
    if args.quick:
        for name, func, tol in QUICK:
            rows = func()
            print(f'## {name}\n{table(rows, True)}')
        return 0
    text = document()
    if args.output == '-':
        print(text)
    else:
        Path(args.output).write_text(text)
        print(f'wrote {args.output}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
