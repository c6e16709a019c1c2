"""README.md and docs/ stay true: every ```python block runs, and every link resolves.

Blocks of one file run in order in one namespace, like a reader pasting them into a session.
Links must stay inside the repository (or be http(s)/mailto, which are not fetched) and reach an
existing file and, for ``page.md#anchor``, an existing heading.
"""

from __future__ import annotations

import difflib
import html
import os
import re
import unicodedata
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_code_blocks_run(page: Path, capsys: pytest.CaptureFixture[str]) -> None:
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for k, block in enumerate(BLOCK.findall(page.read_text(encoding="utf-8"))):
        code = compile(block, f"{page.name}[block {k}]", "exec")
        exec(code, namespace)


# ---------------------------------------------------------------- links
# Every link of README.md and docs/ must work for a reader of the repository: relative links stay
# inside it and reach an existing file (and, with `#anchor`, an existing heading); http(s) and
# mailto links may leave it and are not fetched. Anything else (file: URLs, absolute paths, paths
# that climb out of the repository) is an error.

FENCE = re.compile(r"^\s*(`{3,}|~{3,})")
CODE_SPAN = re.compile(r"(`+)(.+?)\1")
INLINE_LINK = re.compile(
    r"""!?\[(?:[^\[\]]|\[[^\]]*\])*\]         # [text] or ![alt], one level of nested brackets
        \(\s*(<[^>]*>|(?:[^()\s]|\([^()\s]*\))*)  # (target, balanced parentheses allowed
        (?:\s+(?:"[^"]*"|'[^']*'))?\s*\)          #  "optional title")""",
    re.X,
)
REFERENCE_DEFINITION = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)")
AUTOLINK = re.compile(r"<([A-Za-z][A-Za-z0-9+.-]{1,31}:[^<>\s]*)>")
HTML_LINK = re.compile(r"""\b(?:href|src)\s*=\s*["']([^"']*)["']""", re.I)
HTML_ANCHOR = re.compile(r"""<a\s[^>]*\b(?:name|id)\s*=\s*["']([^"']+)["']""", re.I)
ATX_HEADING = re.compile(r"^ {0,3}#{1,6}(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
SETEXT_UNDERLINE = re.compile(r"^ {0,3}(?:=+|-+)[ \t]*$")
SCHEME = re.compile(r"([A-Za-z][A-Za-z0-9+.-]*):")
EXTERNAL_SCHEMES = {"http", "https", "mailto"}
#: Unicode categories github-slugger strips from a heading (all but letters, marks, decimal and
#: letter numbers, `_`, `-` and the space, which becomes `-`).
SLUG_DROP = {
    "No",
    "Pd",
    "Ps",
    "Pe",
    "Pi",
    "Pf",
    "Po",
    "Sm",
    "Sc",
    "Sk",
    "So",
    "Cc",
    "Cf",
    "Co",
    "Cn",
    "Zs",
    "Zl",
    "Zp",
}


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced code blocks, code spans blanked out."""
    out: list[tuple[int, str]] = []
    fence = ""
    for number, line in enumerate(text.splitlines(), 1):
        opening = FENCE.match(line)
        if fence:
            if opening and opening.group(1)[0] == fence[0] and len(opening.group(1)) >= len(fence):
                fence = ""
            continue
        if opening:
            fence = opening.group(1)
            continue
        out.append((number, CODE_SPAN.sub(lambda m: m.group(1) + "x" * len(m.group(2)) + m.group(1), line)))
    return out


def _heading_text(markdown: str) -> str:
    """The text GitHub renders for a heading's inline Markdown."""
    parts = re.split(r"(`+[^`]*`+)", markdown)
    plain = []
    for k, part in enumerate(parts):
        if k % 2:  # a code span: its content, verbatim
            plain.append(part.strip("`"))
            continue
        part = re.sub(r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]\([^)]*\)", r"\1", part)  # links → text
        part = re.sub(r"<[^>]+>", "", part)  # inline HTML
        part = re.sub(r"(\*{1,3}|(?<!\w)_{1,3})(\S(?:.*?\S)?)\1(?!\w)", r"\2", part)  # emphasis
        plain.append(html.unescape(re.sub(r"\\([!-/:-@\[-`{-~])", r"\1", part)))
    return "".join(plain)


def github_slug(heading: str) -> str:
    """GitHub's anchor for a heading (github-slugger): lower case, punctuation and symbols
    dropped (non-ASCII letters such as ``ö`` kept), each space turned into ``-``."""
    kept = (c for c in heading.lower() if c in " -" or unicodedata.category(c) not in SLUG_DROP)
    return "".join(kept).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of a Markdown page: its headings' slugs (``-1``, ``-2`` … for repeats) and
    explicit ``<a name=…>``/``id=…`` targets."""
    found: set[str] = set()
    seen: dict[str, int] = {}
    previous = ""
    for _, line in _prose_lines(page.read_text(encoding="utf-8")):
        found.update(HTML_ANCHOR.findall(line))
        atx = ATX_HEADING.match(line)
        if atx:
            text = atx.group(1) or ""
        elif SETEXT_UNDERLINE.match(line) and previous.strip() and not ATX_HEADING.match(previous):
            text = previous.strip()
        else:
            previous = line
            continue
        previous = ""
        slug = base = github_slug(_heading_text(text))
        while slug in seen:
            seen[base] += 1
            slug = f"{base}-{seen[base]}"
        seen[slug] = 0
        found.add(slug)
    return found


def link_targets(page: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link, image, reference definition, autolink and HTML
    href/src of a Markdown page, outside code."""
    out: list[tuple[int, str]] = []
    for number, line in _prose_lines(page.read_text(encoding="utf-8")):
        for pattern in (INLINE_LINK, REFERENCE_DEFINITION, AUTOLINK, HTML_LINK):
            out += [(number, m.group(1)) for m in pattern.finditer(line)]
    return out


def link_problem(page: Path, target: str, root: Path = ROOT) -> str | None:
    """Why ``target`` (a link on ``page``) is broken for a reader of the repository, or None."""
    target = target.strip()
    if target.startswith("<") and target.endswith(">"):
        target = target[1:-1]
    if not target:
        return "empty link target"
    scheme = SCHEME.match(target)
    if scheme and len(scheme.group(1)) == 1:
        return "absolute filesystem path (a drive letter); link relative to the page instead"
    if scheme:
        if scheme.group(1).lower() in EXTERNAL_SCHEMES:
            return None
        return f"{scheme.group(1)}: URL; only http(s) and mailto links may leave the repository"
    if target.startswith(("/", "\\")):
        return "absolute path; link relative to the page instead"
    if target.startswith("~"):
        return "home-directory path; link relative to the page instead"
    path, hash_sign, fragment = target.partition("#")
    path, fragment = unquote(path.split("?")[0]), unquote(fragment)
    if path:
        lexical = os.path.normpath(os.path.join(page.parent.relative_to(root), path))
        destination = (page.parent / path).resolve()
        climbs_out = lexical == ".." or lexical.startswith(".." + os.sep)
        if climbs_out or not destination.is_relative_to(root.resolve()):
            return "points outside the repository"
        if not destination.exists():
            return f"missing file {lexical}"
    else:
        destination = page
    if not hash_sign:
        return None
    if not fragment:
        return "empty anchor '#'"
    if destination.suffix.lower() == ".md":
        known = anchors(destination)
        if fragment not in known:
            close = difflib.get_close_matches(fragment, sorted(known), n=1)
            hint = f" (did you mean #{close[0]}?)" if close else ""
            where = destination.resolve().relative_to(root.resolve())
            return f"no heading with anchor #{fragment} in {where}{hint}"
        return None
    if destination.is_file() and re.fullmatch(r"L\d+(-L\d+)?", fragment):
        return None
    return f"anchor #{fragment} on a file that is not Markdown"


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    """``page:line: (target) why`` for every broken link of ``page``."""
    name = page.relative_to(root)
    return [
        f"{name}:{number}: ({target}) {problem}"
        for number, target in link_targets(page)
        if (problem := link_problem(page, target, root)) is not None
    ]


#: pages whose links are checked: the documentation, and the benchmark notes it links to
LINKED_PAGES = [*PAGES, *sorted((ROOT / "benchmarks").rglob("*.md"))]


@pytest.mark.parametrize("page", LINKED_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_stay_in_the_repository_and_resolve(page: Path) -> None:
    problems = broken_links(page)
    assert not problems, "broken links:\n" + "\n".join(problems)


@pytest.mark.parametrize(
    ("heading", "slug"),
    [
        # expectations worked out by hand from GitHub's rules, not produced by github_slug
        ("Constraint forces, eq. (7), and their sign", "constraint-forces-eq-7-and-their-sign"),
        ("Integrating (18b): the constants c_β", "integrating-18b-the-constants-c_β"),
        ("Lindelöf's equations (22): Lindelöf's error", "lindelöfs-equations-22-lindelöfs-error"),
        ("`compare_models`", "compare_models"),
        ("The **new** form (40)", "the-new-form-40"),
        ("Chetaev – vakonomic", "chetaev--vakonomic"),
        ("y ẋ − x ẏ = 0", "y-ẋ--x-ẏ--0"),
        ("[A link](x.md) here", "a-link-here"),
    ],
)
def test_github_slug(heading: str, slug: str) -> None:
    assert github_slug(_heading_text(heading)) == slug


def test_broken_links_are_reported(tmp_path: Path) -> None:
    """The checker itself: each kind of bad link is reported, with its line; good ones are not."""
    root = tmp_path / "repo"
    (root / "docs").mkdir(parents=True)
    (tmp_path / "outside.md").write_text("# Outside\n", encoding="utf-8")
    (root / "docs" / "other.md").write_text(
        "# Other page\n\n## Lindelöf's equations (22)\n\n## Notes\n\n## Notes\n\n"
        "Setext heading\n--------------\n\n```text\n# not a heading\n```\n",
        encoding="utf-8",
    )
    good = [
        "[a](other.md)",
        "[a](other.md#other-page)",
        "[a](other.md#lindelöfs-equations-22)",
        "[a](other.md#lindel%C3%B6fs-equations-22)",
        "[a](other.md#notes-1)",
        "[a](other.md#setext-heading)",
        "[a](#this-page)",
        "[a](../docs/other.md)",
        "[a](https://example.org/x_(y))",
        "<https://example.org>",
        "[a](mailto:a@example.org)",
        "![i](other.md 'title')",
        "`[not a link](../../nowhere.md)`",
    ]
    bad = [
        "[a](../../outside.md)",
        "[a](file:///etc/passwd)",
        "[a](/etc/passwd)",
        "[a](C:/Users/x.md)",
        "[a](missing.md)",
        "[a](other.md#missing)",
        "[a](other.md#notes-2)",
        "[a](other.md#not-a-heading)",
        "[a](#nowhere)",
        "[a](other.md#)",
        '<a href="../../outside.md">a</a>',
        "[r]: ../../outside.md",
        "<file:///tmp/x>",
        "[a](~/notes.md)",
    ]
    page = root / "docs" / "page.md"
    page.write_text("# This page\n\n" + "\n".join(good + bad) + "\n", encoding="utf-8")
    problems = broken_links(page, root)
    first_bad = 3 + len(good)
    lines = [int(p.split(":")[1]) for p in problems]
    assert lines == list(range(first_bad, first_bad + len(bad))), "\n".join(problems)
    assert "points outside the repository" in problems[0]
    assert "file: URL" in problems[1] and "missing file docs/missing.md" in problems[4]


def test_every_public_name_is_in_the_api_reference() -> None:
    """Each name of ``chaplygin.__all__`` is listed in docs/api/index.md (so the site documents it)."""
    import chaplygin

    listed = (ROOT / "docs" / "api" / "index.md").read_text(encoding="utf-8")
    missing = [n for n in chaplygin.__all__ if n != "__version__" and f"`{n}`" not in listed]
    assert not missing, f"add {missing} to docs/api/index.md and its page"
