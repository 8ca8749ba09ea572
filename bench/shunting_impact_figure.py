"""
The shunting impact with category buffers (docs/real_trains.md "Shunting impact").

Runs ``config/shunting_impact.yaml`` through the offline command as shipped (the wagon's
buffers UIC 526-1 category A), then with the wagon's buffers the library's category C entry
and with the library's plain loaded wagon (the paper's linear law); prints the rows of the
docs' table (impact speed, energy of the relative motion, peak force, compression beyond the
gap, parting speed) and writes ``docs/figures/real_trains/shunting_impact_buffers.png``
(coupler force against compression: the loading and unloading branches of each impact).

    python bench/shunting_impact_figure.py
"""
from __future__ import annotations

import os
from pathlib import Path
import sys
import tempfile

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from train_dynamics import topics  # noqa: E402
from train_dynamics.cli import offline  # noqa: E402
from train_dynamics.physics.config import consist  # noqa: E402
from train_dynamics.recording.bags import read_topics  # noqa: E402
import yaml  # noqa: E402

CONFIG = ROOT / 'config'
FIGURE = ROOT / 'docs' / 'figures' / 'real_trains' / 'shunting_impact_buffers.png'
DURATION = 2.0


def variant(tmp: Path, name: str, wagon: str, types: dict | None = None) -> Path:
    """Write the shipped parameter and consist files with the wagon's type replaced."""
    doc = yaml.safe_load((CONFIG / 'consist_shunting_impact.yaml').read_text())
    doc['vehicles'][0]['type'] = wagon
    if types:
        doc['vehicle_types'] = types
    (tmp / f'consist_{name}.yaml').write_text(yaml.safe_dump(doc))
    params = (CONFIG / 'shunting_impact.yaml').read_text().replace(
        'consist_file: consist_shunting_impact.yaml', f'consist_file: consist_{name}.yaml')
    path = tmp / f'{name}.yaml'
    path.write_text(params)
    return path


def impact(params: Path, out: Path) -> dict:
    """Run one impact; return its figures and its force-compression curve."""
    assert offline.main(['simulate', '--params', str(params), '--duration', str(DURATION),
                         '--output', str(out), '-q']) == 0
    cp = [m for _, _, m in read_topics(str(out), [topics.COUPLERS_TOPIC])]
    co = [m for _, _, m in read_topics(str(out), [topics.COACHES_TOPIC])]
    y = np.array([m.position[0] for m in cp])
    force = np.array([m.effort[0] for m in cp])
    v = np.array([m.velocity for m in co])
    gap = 1.0                    # the locomotive's front-end buffer free play [m]
    contact = int(np.argmax(y < -gap))
    lib = consist.library_types()
    wagon = lib['freight_wagon_loaded']
    loco = lib['electric_freight_locomotive']
    inertia = [t['mass'] * (1.0 + t['rotating_mass_factor']) for t in (wagon, loco)]
    mu = inertia[0] * inertia[1] / sum(inertia)
    v_impact = v[contact - 1, 1] - v[contact - 1, 0]
    touching = force < 0.0
    return {'v_impact': v_impact, 'energy': 0.5 * mu * v_impact ** 2,
            'peak': -force.min(), 'compression': -y.min() - gap,
            'v_part': v[-1, 0] - v[-1, 1],
            'curve': (1e3 * (-y[touching] - gap), -force[touching] / 1e3)}


def main() -> None:
    """Run the three impacts, print the table rows, write the figure."""
    library = yaml.safe_load((CONFIG / 'vehicles.yaml').read_text())
    category_c = library['buffer_categories']['uic_526_1_category_c']
    plain = consist.library_types()['freight_wagon_loaded']
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        runs = {
            'category A (library type)': impact(CONFIG / 'shunting_impact.yaml', tmp / 'a'),
            'category C (70 kJ)': impact(variant(tmp, 'c', 'wagon_c',
                                                 {'wagon_c': {**plain, **category_c}}),
                                         tmp / 'c'),
            'paper law, freight_wagon_loaded': impact(
                variant(tmp, 'plain', 'freight_wagon_loaded'), tmp / 'plain'),
        }
    fig = Figure(figsize=(7.0, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for name, r in runs.items():
        print(f'| {name} | {r["v_impact"]:.3f} m/s | {r["energy"] / 1e3:.1f} kJ | '
              f'{r["peak"] / 1e3:.0f} kN | {1e3 * r["compression"]:.0f} mm | '
              f'{r["v_part"]:.3f} m/s |')
        ax.plot(*r['curve'], label=f'{name}: {r["peak"] / 1e3:.0f} kN')
    ax.set_xlabel('compression of the coupling beyond the gap [mm]')
    ax.set_ylabel('buffer force [kN]')
    ax.set_title('locomotive into a standing wagon at 5.1 km/h')
    ax.grid(True, alpha=0.3)
    ax.legend(loc='upper left')
    os.makedirs(FIGURE.parent, exist_ok=True)
    fig.savefig(FIGURE, dpi=110, bbox_inches='tight')
    print(f'wrote {FIGURE}')


if __name__ == '__main__':
    main()
