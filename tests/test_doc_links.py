"""Every relative link in the README and the hand-written docs resolves: the
file exists and, for a link into a Markdown file, so does the heading its
anchor names (GitHub's rule: lower case, punctuation dropped, spaces to
hyphens, a repeated heading numbered). The campaigns' generated reports in
docs/experiments/*/ are left out."""

import re
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [
    ROOT / "README.md",
    *sorted((ROOT / "docs").glob("*.md")),
    *sorted((ROOT / "docs" / "experiments").glob("*.md")),
]
LINK = re.compile(r"\]\(([^)\s]+)\)")
CODE_BLOCK = re.compile(r"^```.*?^```", flags=re.S | re.M)


def Slug(heading: str) -> str:
    text = heading.strip().lower().replace("`", "")
    kept = (c for c in text if c in " -_" or unicodedata.category(c)[0] in "LN")
    return "".join(kept).replace(" ", "-")


def Anchors(path: Path) -> set[str]:
    anchors, seen = set(), {}
    text = CODE_BLOCK.sub("", path.read_text(encoding="utf-8"))
    for match in re.finditer(r"^#{1,6}\s+(.*)$", text, flags=re.M):
        slug = Slug(match.group(1))
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        anchors.add(slug if count == 0 else f"{slug}-{count}")
    return anchors


def test_slug_follows_githubs_rule():
    assert (
        Slug("People: SM²ITH (Sections IV.B–IV.C)") == "people-sm²ith-sections-ivbivc"
    )
    assert Slug("Contact in the `safe` variant") == "contact-in-the-safe-variant"


@pytest.mark.parametrize("doc", DOCS, ids=[str(d.relative_to(ROOT)) for d in DOCS])
def test_links_resolve(doc):
    text = CODE_BLOCK.sub("", doc.read_text(encoding="utf-8"))
    broken = []
    for target in LINK.findall(text):
        if target.startswith(("http://", "https://", "mailto:")):
            continue
        path, _, anchor = target.partition("#")
        linked = (doc.parent / path).resolve() if path else doc
        if not linked.exists():
            broken.append(f"{target}: no such file")
        elif anchor and linked.suffix == ".md" and anchor not in Anchors(linked):
            broken.append(f"{target}: no such heading")
    assert not broken, broken
