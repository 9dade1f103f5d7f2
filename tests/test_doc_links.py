"""Every relative link of README.md and of the Markdown pages under docs/ points at a file that
exists, and a ``#anchor`` on a Markdown page at one of its headings (issue 45: the README is a
front door whose links lead into docs/; the site build checks the pages' own links, not the
README's).  Links inside code are not links.  Well under a second."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE = re.compile(r"^(```|~~~).*?^\1[^\n]*$|`[^`\n]*`", flags=re.M | re.S)


def _links(text: str) -> list[str]:
    """The link targets of a Markdown text, code blocks and code spans left out."""
    return LINK.findall(CODE.sub("", text))


def _anchors(page: Path) -> set[str]:
    """The ids of a page's headings as MkDocs (toc) and GitHub make them: lower case, punctuation
    dropped, spaces as hyphens."""
    headings = re.findall(r"^#{1,6}\s+(.*?)\s*#*\s*$", CODE.sub("", page.read_text()), flags=re.M)
    return {re.sub(r"[\s]+", "-", re.sub(r"[^\w\s-]", "", h.lower()).strip()) for h in headings}


def _relative(target: str) -> bool:
    return not re.match(r"^[a-z][a-z0-9+.-]*:", target, flags=re.I) and not target.startswith("/")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_point_at_existing_files_and_headings(page):
    broken = []
    for target in filter(_relative, _links(page.read_text())):
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(f"{target}: no {file.relative_to(ROOT) if file.is_relative_to(ROOT) else file}")
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
            broken.append(f"{target}: no heading #{anchor} in {file.relative_to(ROOT)}")
    assert not broken, f"{page.relative_to(ROOT)}: " + "; ".join(broken)


def test_the_readme_links_into_the_documentation():
    """The README is the front door: it links the install page, the first hour, the catalogue and the tutorials."""
    targets = {t.partition("#")[0] for t in _links((ROOT / "README.md").read_text())}
    for page in ("docs/install.md", "docs/first-hour.md", "docs/catalogue.md", "docs/tutorials/swap-controller.md",
                 "docs/figures/pid_fopdt.png"):
        assert page in targets, page
