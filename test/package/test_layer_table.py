"""docs/development.md's layer table names only modules that exist, in the folder it names."""
from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / 'train_dynamics'


def _rows():
    text = (ROOT / 'docs' / 'development.md').read_text(encoding='utf-8')
    for line in text.splitlines():
        m = re.match(r'\| `([a-z_]+)/` \| (.*?) \| [^|]* \|$', line)
        if m:
            yield m.group(1), m.group(2)


def test_every_module_the_layer_table_names_exists_in_its_folder():
    rows = dict(_rows())
    assert {'physics', 'recording', 'ros', 'cli', 'testing', 'simulation'} <= set(rows)
    missing = []
    for folder, what in rows.items():
        here = {p.stem for p in (PACKAGE / folder).rglob('*.py')}
        here |= {p.name for p in (PACKAGE / folder).rglob('*') if p.is_dir()}
        for name in re.findall(r'`([A-Za-z_][A-Za-z0-9_]*)/?`', what):
            if name not in here:
                missing.append(f'{folder}/{name}')
    assert not missing, missing


def test_every_folder_of_the_package_has_a_row():
    folders = {p.name for p in PACKAGE.iterdir() if p.is_dir() and p.name != '__pycache__'}
    assert folders <= set(dict(_rows()))
