"""The documentation holds together: README.md is a front door of at most 250 lines, every page
under docs/ is linked from docs/index.md, every relative link of README.md and docs/**/*.md names
a file of the repository (and an anchor a heading of it, by GitHub's rule), none leaves the
repository, and docs/formats.md is what its generator writes from the loader's declarations.

Each check is a function of the text, so the planted faults below show that it can fail."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"
README = REPO / "README.md"
README_LINES = 250

FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.S | re.M)
CODE_SPAN = re.compile(r"(`+)(?!`).+?(?<!`)\1(?!`)", re.S)
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_LINK = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+\"[^\"]*\")?\s*$", re.M)
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$", re.M)
EXTERNAL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")  # http:, https:, mailto:


def prose(text: str) -> str:
    """The text without fenced code blocks and code spans (a link there is no link)."""
    return CODE_SPAN.sub("", FENCE.sub("", text))


def links(text: str) -> list[str]:
    """The targets of the Markdown links and images of a page (inline and reference style)."""
    plain = prose(text)
    return INLINE_LINK.findall(plain) + REFERENCE_LINK.findall(plain)


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: its rendered text (code spans and links by their text)
    lower-cased, every character but letters, digits, '-', '_' and spaces dropped, spaces to '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"`+([^`]*)`+", r"\1", text)
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def anchors(text: str) -> set[str]:
    """The anchors of a page's headings; a repeated heading gets -1, -2, ... as on GitHub."""
    seen: dict[str, int] = {}
    out = set()
    for _, title in HEADING.findall(FENCE.sub("", text)):
        base = slug(title)
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f"{base}-{count}")
    return out


def repository_files(repo: Path) -> set[Path]:
    """The files a clone has: tracked ones and the untracked ones git does not ignore (a page
    being written); where git cannot tell (no checkout), every file below ``repo``."""
    try:
        listed = subprocess.run(["git", "-C", str(repo), "ls-files", "--cached", "--others", "--exclude-standard",
                                 "-z"], capture_output=True, text=True, check=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError):
        return {p.resolve() for p in repo.rglob("*") if p.is_file()}
    return {(repo / name).resolve() for name in listed.split("\0") if name}


def link_faults(page: Path, repo: Path, files: set[Path]) -> list[str]:
    """Every relative link of ``page`` that names no file or folder of the repository, leaves it,
    or names an anchor its target has no heading for."""
    faults = []
    root = repo.resolve()
    folders = {parent for f in files for parent in f.parents}
    for target in links(page.read_text(encoding="utf-8")):
        if EXTERNAL.match(target):
            continue
        where = f"{page.relative_to(repo)}: ({target})"
        path_part, _, anchor = target.partition("#")
        path = (page.parent / path_part).resolve() if path_part else page.resolve()
        if root != path and root not in path.parents:
            faults.append(f"{where} leaves the repository")
        elif path not in files and path not in folders:
            faults.append(f"{where} names no file of the repository")
        elif anchor and path.suffix == ".md" and anchor not in anchors(path.read_text(encoding="utf-8")):
            faults.append(f"{where} names no heading of {path.relative_to(root)}")
    return faults


def unlisted_pages(index: Path, docs: Path) -> list[str]:
    """The Markdown pages under ``docs`` (the index aside) that ``index`` does not link to."""
    linked = {(index.parent / t.partition("#")[0]).resolve() for t in links(index.read_text(encoding="utf-8"))
              if not EXTERNAL.match(t) and t.partition("#")[0]}
    return [str(p.relative_to(docs)) for p in sorted(docs.rglob("*.md")) if p != index and p.resolve() not in linked]


def pages(repo: Path) -> list[Path]:
    return [repo / "README.md", *sorted((repo / "docs").rglob("*.md"))]


# --------------------------------------------------------------------------- the repository's docs


def test_readme_is_a_front_door():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= README_LINES, f"README.md has {len(text.splitlines())} lines"
    assert "docs/index.md" in links(text), "README.md links no docs/index.md"


@pytest.mark.parametrize("page", pages(REPO), ids=lambda p: str(p.relative_to(REPO)))
def test_every_link_resolves_in_the_repository(page):
    assert link_faults(page, REPO, repository_files(REPO)) == []


def test_every_page_is_linked_from_the_index():
    assert unlisted_pages(DOCS / "index.md", DOCS) == []


def test_formats_reference_is_what_the_loader_declares():
    from mta_sim_ros.tools import formats

    written = (DOCS / "formats.md").read_text(encoding="utf-8")
    assert written == formats.markdown(), f"docs/formats.md is stale: run `{formats.COMMAND}`"


# --------------------------------------------------------------------------- the checks can fail


def test_slugs_follow_github():
    assert slug("Timing, and the default integrator") == "timing-and-the-default-integrator"
    assert slug("A cart (`carts[k]`)") == "a-cart-cartsk"
    assert slug("Steering actuator (`steering_actuator`)") == "steering-actuator-steering_actuator"
    assert slug("See [the model](model.md) **now**") == "see-the-model-now"
    assert anchors("# A\n## A\n```\n# not a heading\n```\n### A\n") == {"a", "a-1", "a-2"}


def test_planted_faults_are_found(tmp_path):
    (tmp_path / "docs" / "sub").mkdir(parents=True)
    (tmp_path / "docs" / "good.md").write_text("# Good\n\n## A part\n")
    (tmp_path / "docs" / "sub" / "deep.md").write_text("# Deep\n")
    page = tmp_path / "docs" / "index.md"
    page.write_text("# Index\n\n[good](good.md), [part](good.md#a-part), [self](#index), [web](https://x.org)\n"
                    "`[code](nowhere.md)`\n```\n[fenced](nowhere.md)\n```\n"
                    "[gone](missing.md) [bad anchor](good.md#no-part) [out](../../outside.md) ![img](pic.png)\n")
    files = {p.resolve() for p in tmp_path.rglob("*") if p.is_file()}
    faults = link_faults(page, tmp_path, files)
    assert [f.split("(", 1)[1].split(")")[0] for f in faults] == [
        "missing.md", "good.md#no-part", "../../outside.md", "pic.png"], faults
    assert unlisted_pages(page, tmp_path / "docs") == ["sub/deep.md"]
