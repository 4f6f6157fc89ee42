"""The manual in docs/ builds as a site without a warning, and every relative link resolves (issue 28).

Two checks:

* Sphinx + MyST build the site (``sphinx-build -W --keep-going -n -b html docs <tmp>``, as
  docs/testing.md tells a user to) with exit status 0 and not one ``WARNING``. Sphinx itself
  then also refuses a page missing from the contents, an image that is not there, and a link
  between pages (``page.md``, ``page.md#section``, ``#section``) that does not resolve.
* Every relative link and image of ``README.md`` (not part of the site: GitHub renders it) and of
  every docs page that is in the build resolves: the target file exists inside the repository
  (links out of docs/, e.g. ``../bench/nav2_maps.py``, included), and a ``#anchor`` names a
  heading of the target Markdown file. Anchors are computed as MyST computes them for
  ``myst_heading_anchors`` (GitHub-style slugs over the heading's text and code, ``-1``, ``-2``
  for repeats; ``myst_parser.slugs``), from the same Markdown parser (markdown-it-py), so a
  README link that works here works on GitHub and in the site. The anchors computed for each
  built page are also checked against the ids in its HTML, so the two cannot drift apart.

External links (http, https, mailto) are skipped: the tests run without a network, and whether
a web page still exists is no property of this repository. No speed is asserted.
"""
from __future__ import annotations

import os
import re
import runpy
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
README = REPO / "README.md"
EXTERNAL_SCHEMES = ("http", "https", "mailto", "ftp")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """The site built from docs/ into a temporary folder (nothing is written under docs/)."""
    out = tmp_path_factory.mktemp("docs_html")
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    got = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-b", "html", str(DOCS), str(out)],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    return got, out


def _output(got: subprocess.CompletedProcess) -> str:
    """The build's output, without its per-file progress lines ("copying images... [ 42%] x.png")."""
    stdout = "\n".join(line for line in got.stdout.splitlines() if "%] " not in line)
    return f"--- sphinx-build exit status {got.returncode}\n--- stdout:\n{stdout}\n--- stderr:\n{got.stderr}"


def test_the_manual_builds_without_a_warning(site):
    got, out = site
    text = got.stdout + got.stderr
    warnings = [line for line in text.splitlines() if "WARNING" in line or "ERROR" in line]
    assert got.returncode == 0 and not warnings, "\n".join(warnings) + "\n" + _output(got)
    assert (out / "index.html").is_file(), _output(got)


# --- links --------------------------------------------------------------------------------------
def _markdown():
    from markdown_it import MarkdownIt

    return MarkdownIt("commonmark").enable("table")


def _slug_functions():
    """MyST's own slug functions (myst-parser >= 5.2 has them in ``myst_parser.slugs``; older
    releases compute the same GitHub-style slug in ``default_slugify``)."""
    try:
        from myst_parser.slugs import github_slugify, unique_slug
    except ImportError:  # myst-parser 4.x - 5.1
        from myst_parser.mdit_to_docutils.base import default_slugify as github_slugify

        def unique_slug(slug: str, existing) -> str:
            uniq, i = slug, 1
            while uniq in existing:
                uniq, i = f"{slug}-{i}", i + 1
            return uniq
    return github_slugify, unique_slug


def heading_anchors(path: Path, depth: int) -> set[str]:
    """The anchors MyST gives the headings of ``path`` down to level ``depth`` (its
    ``compute_unique_slug``: the text and inline code of the heading, slugged, repeats numbered)."""
    slugify, unique = _slug_functions()
    tokens = _markdown().parse(path.read_text(encoding="utf-8"))
    anchors: set[str] = set()
    for i, tok in enumerate(tokens):
        if tok.type != "heading_open" or int(tok.tag[1:]) > depth:
            continue
        title = "".join(c.content for c in tokens[i + 1].children or [] if c.type in ("text", "code_inline"))
        slug = slugify(title)
        if slug:
            anchors.add(unique(slug, anchors))
    return anchors


def links(path: Path) -> list[tuple[int, str]]:
    """(line, target) of every link and image of a Markdown file (code blocks and spans excluded)."""
    found = []
    for tok in _markdown().parse(path.read_text(encoding="utf-8")):
        if tok.type != "inline":
            continue
        line = tok.map[0] + 1 if tok.map else 0
        for child in tok.children or []:
            if child.type == "link_open":
                found.append((line, str(child.attrs.get("href", ""))))
            elif child.type == "image":
                found.append((line, str(child.attrs.get("src", ""))))
    return found


def pages_in_the_build(out: Path) -> list[Path]:
    """The docs pages Sphinx turned into HTML (docs/X.md -> X.html)."""
    pages = [p for p in sorted(DOCS.rglob("*.md")) if "_build" not in p.relative_to(DOCS).parts
             and (out / p.relative_to(DOCS).with_suffix(".html")).is_file()]
    assert len(pages) >= 10, pages
    return pages


def broken_links(path: Path, depth: int, anchors_of) -> list[str]:
    problems = []
    for line, href in links(path):
        where = f"{path.relative_to(REPO)}:{line}: {href!r}"
        parts = urlsplit(href)
        if parts.scheme in EXTERNAL_SCHEMES or href.startswith("//"):
            continue  # not checked: no network here (see the module docstring)
        if parts.scheme or parts.netloc:
            problems.append(f"{where}: unexpected scheme (use a relative path or an http(s) address)")
            continue
        target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
        if target != REPO and REPO not in target.parents:
            problems.append(f"{where}: points outside the repository")
        elif not target.exists():
            problems.append(f"{where}: {target.relative_to(REPO)} does not exist")
        elif parts.fragment:
            if target.suffix != ".md" or not target.is_file():
                problems.append(f"{where}: an anchor into {target.relative_to(REPO)}, which is not a Markdown page")
            elif unquote(parts.fragment) not in anchors_of(target, depth):
                problems.append(f"{where}: {target.relative_to(REPO)} has no heading with the anchor "
                                f"#{parts.fragment} (its anchors: {sorted(anchors_of(target, depth))})")
    return problems


def test_every_relative_link_of_the_readme_and_the_manual_resolves(site):
    _, out = site
    depth = int(runpy.run_path(str(DOCS / "conf.py"))["myst_heading_anchors"])
    cache: dict[Path, set[str]] = {}

    def anchors_of(target: Path, depth: int) -> set[str]:
        if target not in cache:
            cache[target] = heading_anchors(target, depth)
        return cache[target]

    problems = []
    checked = 0
    for page in [README, *pages_in_the_build(out)]:
        problems += broken_links(page, depth, anchors_of)
        checked += len(links(page))
    for page in pages_in_the_build(out):  # the anchors computed here are the ones the site has
        html = (out / page.relative_to(DOCS).with_suffix(".html")).read_text(encoding="utf-8")
        ids = set(re.findall(r'\sid="([^"]+)"', html))
        missing = sorted(anchors_of(page, depth) - ids)
        if missing:
            problems.append(f"{page.relative_to(REPO)}: anchors computed here but not in the built page: {missing}")
    assert checked > 100  # the checker sees the links (a parser change that found none would pass)
    assert not problems, "\n".join(problems)


def test_the_link_checker_catches_what_it_should(tmp_path, monkeypatch):
    """A missing file, a missing anchor and a path out of the repository are reported; an external
    link, a link inside a code span, a page's own heading and a file outside docs/ are not."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "nav2_maps.py").write_text("")
    (tmp_path / "docs" / "testing.md").write_text("# Testing\n\n## Building the docs\n\n## Building the docs\n")
    page = tmp_path / "docs" / "page.md"
    page.write_text("# A page\n\n## Two `words`, here\n\n[ok](#two-words-here) [ext](https://example.org/x#y) "
                    "`[code](nope.md)` [file](nope.md) [anchor](testing.md#no-such-heading) [out](../../x.md) "
                    "[good](testing.md#building-the-docs-1) [bench](../bench/nav2_maps.py)\n\n"
                    "```md\n[fenced](nope.md)\n```\n")
    monkeypatch.setitem(globals(), "REPO", tmp_path)  # what broken_links resolves against
    problems = broken_links(page, 4, heading_anchors)
    assert len(problems) == 3, problems
    assert "docs/nope.md does not exist" in problems[0]
    assert "#no-such-heading" in problems[1]
    assert "outside the repository" in problems[2]


def test_the_readme_stays_a_page():
    """The README is the one-page overview a newcomer reads (at most 150 lines); the rest is the manual."""
    lines = README.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "# AmbieGen-ROS"
    assert len(lines) <= 150, f"README.md has {len(lines)} lines: move detail into docs/ (the manual)"
