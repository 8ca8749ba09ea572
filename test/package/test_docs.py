"""The README and the manual in docs/: every relative link reaches a file and a heading."""
from pathlib import Path
import re

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]
_FENCE = re.compile(r'```.*?```', re.S)
_LINK = re.compile(r'\]\(([^)\s]+)\)')


def _text(page: Path) -> str:
    """Return the page without its code blocks (a `](` there is not a link)."""
    return _FENCE.sub('', page.read_text(encoding='utf-8'))


def _anchors(page: Path) -> set[str]:
    """Return the heading anchors of a markdown page, as GitHub spells them."""
    out = set()
    for heading in re.findall(r'^#+ (.*)$', _text(page), re.M):
        slug = re.sub(r'[^\w\- ]', '', heading.strip().lower())
        out.add(slug.replace(' ', '-'))
    return out


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_resolve(page):
    """Each relative link of the page names an existing file and, with #, one of its headings."""
    bad = []
    for target in _LINK.findall(_text(page)):
        if re.match(r'[a-z]+:', target):
            continue
        path, _, anchor = target.partition('#')
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(f'{target}: no such file')
        elif anchor and dest.suffix == '.md' and anchor not in _anchors(dest):
            bad.append(f'{target}: no heading #{anchor}')
    assert not bad, f'{page.relative_to(REPO)}: ' + '; '.join(bad)


def test_every_manual_page_is_in_the_index():
    """docs/README.md links every page of the manual."""
    index = _text(REPO / 'docs' / 'README.md')
    missing = [p.name for p in PAGES[1:] if p.name != 'README.md' and f'({p.name})' not in index]
    assert not missing, f'docs/README.md does not list {missing}'


def test_the_docs_show_the_generated_inputs_table():
    """docs/ros_interface.md holds the inputs table exactly as the input table prints it."""
    from train_dynamics.input_kinds import INPUT_KINDS, markdown_table

    page = (REPO / 'docs' / 'ros_interface.md').read_text(encoding='utf-8')
    table = markdown_table()
    assert table in page, 'regenerate: python -m train_dynamics.input_kinds'
    assert len(table.splitlines()) == len(INPUT_KINDS) + 2
