"""The README and the pages of ``docs/`` point only at things that exist.

For ``README.md`` and every ``docs/*.md``:

- every relative Markdown link and image (``[text](path)``, ``![alt](path)``, ``<img src>``)
  names a file of the repository, and every ``#anchor`` in a link is a heading of the page
  it points to, slugged as GitHub slugs headings (lower case, punctuation dropped, each
  space a hyphen, ``-1``, ``-2`` ... for repeats);
- every backticked repository path (a token with a ``/`` ending in ``.py``, ``.md``,
  ``.toml``, ``.png`` or ``.csv``, such as ``planners/optimal.py``) exists;
- nothing refers to documents outside the repository: no ``SPEC`` reference (the design
  brief is not part of the repository; ``docs/design.md`` is) and no paper line numbers
  (``l. 772``, ``line 940``: they point into a LaTeX file the repository does not hold; the
  published paper's equation, section, table and figure numbers are what a reader can
  follow);
- the README stays the front door: at most :data:`README_MAX_LINES` lines.

The checks are plain functions of a page's text, so the last tests hold them to pages made
up to break each rule.
"""

from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parent.parent
README_MAX_LINES = 250
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
INLINE_CODE = re.compile(r"(`+)(.+?)\1")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HTML_SOURCE = re.compile(r"<(?:img|a)\b[^>]*?\b(?:src|href)\s*=\s*\"([^\"]+)\"", re.IGNORECASE)
PATH_TOKEN = re.compile(r"^[\w.\-/]+\.(?:py|md|toml|png|csv)$")
#: "SPEC 4", "SPEC 3.2b", "the SPEC's form": the design brief outside the repository.
SPEC_REFERENCE = re.compile(r"\bSPEC\b")
#: "l. 772", "(l. 936-941", "paper l. 940", "line 817", "lines 40-45".
LINE_REFERENCE = re.compile(r"(?<![A-Za-z])l\.\s?\d|\blines?\s+\d", re.IGNORECASE)


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of the lines outside fenced code blocks."""
    out, fenced = [], False
    for number, line in enumerate(text.splitlines(), start=1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            out.append((number, line))
    return out


def slug(heading: str) -> str:
    """GitHub's anchor for a heading's text (before duplicates are numbered)."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)  # \w keeps letters, digits and underscores
    return text.replace(" ", "-")


def anchors(text: str) -> set[str]:
    """Every heading anchor of a page, duplicates numbered as GitHub numbers them."""
    seen: dict[str, int] = {}
    out = set()
    for _, line in _prose_lines(text):
        match = HEADING.match(line)
        if not match:
            continue
        base = slug(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f"{base}-{count}")
    return out


def link_problems(page: Path, text: str, root: Path = ROOT) -> list[str]:
    """Links and images of ``text`` (the page at ``page``) that point at nothing."""
    problems = []
    for number, line in _prose_lines(text):
        prose = INLINE_CODE.sub("", line)
        targets = LINK.findall(prose) + HTML_SOURCE.findall(prose)
        for target in targets:
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):  # http:, https:, mailto:
                continue
            path_part, _, anchor = target.partition("#")
            path_part = unquote(path_part)
            where = f"{page.name}:{number}: {target}"
            if path_part:
                resolved = (page.parent / path_part).resolve()
                if not resolved.is_relative_to(root.resolve()):
                    problems.append(f"{where} points outside the repository")
                    continue
                if not resolved.exists():
                    problems.append(f"{where} names no file")
                    continue
            else:
                resolved = page
            if anchor:
                if resolved.suffix != ".md" or resolved.is_dir():
                    problems.append(f"{where}: an anchor into something that is not a page")
                    continue
                target_text = text if resolved == page else resolved.read_text(encoding="utf-8")
                if anchor not in anchors(target_text):
                    problems.append(f"{where}: no heading {anchor!r} in {resolved.name}")
    return problems


def path_problems(page: Path, text: str, root: Path = ROOT) -> list[str]:
    """Backticked repository paths of ``text`` that name no file."""
    problems = []
    for number, line in _prose_lines(text):
        for _, code in INLINE_CODE.findall(line):
            for token in code.split():
                token = token.strip("\"'(),;:")
                if "/" not in token or "://" in token or not PATH_TOKEN.match(token):
                    continue
                if not (root / token).is_file():
                    problems.append(f"{page.name}:{number}: `{token}` names no file")
    return problems


def outside_references(page: Path, text: str) -> list[str]:
    """References to documents outside the repository: the design brief, paper line numbers."""
    problems = []
    for number, line in enumerate(text.splitlines(), start=1):
        for pattern, what in ((SPEC_REFERENCE, "the design brief (SPEC)"), (LINE_REFERENCE, "a paper line number")):
            match = pattern.search(line)
            if match:
                context = line[max(0, match.start() - 30) : match.end() + 30]
                problems.append(f"{page.name}:{number}: {what}: ...{context}...")
    return problems


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_links_and_images_point_at_files_and_headings(page):
    problems = link_problems(page, page.read_text(encoding="utf-8"))
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_backticked_paths_exist(page):
    problems = path_problems(page, page.read_text(encoding="utf-8"))
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_no_references_outside_the_repository(page):
    problems = outside_references(page, page.read_text(encoding="utf-8"))
    assert not problems, "\n".join(problems)


def test_the_readme_is_short():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines: at most {README_MAX_LINES}"


def test_the_docs_exist():
    names = {p.name for p in PAGES}
    assert {"README.md", "design.md", "results.md"} <= names, sorted(names)


# ------------------------------------------------------------- the checks can fail


def test_slugs_follow_github():
    assert slug("Two worlds") == "two-worlds"
    assert slug("The model and the API") == "the-model-and-the-api"
    assert slug("`swiptopt.kernel`: the step") == "swiptoptkernel-the-step"
    assert slug("Theorem 1: the LP bounds every non-anticipative policy") == (
        "theorem-1-the-lp-bounds-every-non-anticipative-policy"
    )
    assert slug("K, the reward_weight & more") == "k-the-reward_weight--more"
    assert anchors("# A\n## A\n```\n# not a heading\n```\n### B\n") == {"a", "a-1", "b"}


def test_a_broken_page_is_caught(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "other.md").write_text("# Other\n\n## Real section\n", encoding="utf-8")
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "there.py").write_text("", encoding="utf-8")
    page = tmp_path / "README.md"
    text = "\n".join([
        "# Title",
        "[fine](docs/other.md#real-section) [also fine](#title) ![fig](docs/other.md)",
        "[missing](docs/nowhere.md) ![missing figure](docs/fig.png)",
        "[bad anchor](docs/other.md#no-such-section) [bad local anchor](#nothing)",
        "`pkg/there.py` exists, `pkg/gone.py` does not, `python pkg/also_gone.py --flag` neither",
        "[outside](../../etc/passwd.md) [web](https://example.org/x.md#y)",
        "the kernel (SPEC 4) and the paper's claim (l. 772-773), see line 940",
        "```",
        "[in a code block](nowhere.md) `pkg/in_block.py`",
        "```",
    ])
    links = link_problems(page, text, root=tmp_path)
    assert len(links) == 5, links
    assert any("nowhere.md names no file" in p for p in links)
    assert any("fig.png names no file" in p for p in links)
    assert any("no heading 'no-such-section'" in p for p in links)
    assert any("no heading 'nothing'" in p for p in links)
    assert any("outside the repository" in p for p in links)
    paths = path_problems(page, text, root=tmp_path)
    assert [p.split("`")[1] for p in paths] == ["pkg/gone.py", "pkg/also_gone.py"], paths
    outside = outside_references(page, text)
    assert len(outside) == 2 and all(":7:" in p for p in outside), outside
    assert len(outside_references(page, "see line 940")) == 1
    assert not outside_references(page, "a model. 5 layouts; the spec's own words; eq. 23 (Section III-B)")
