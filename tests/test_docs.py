"""README.md and docs/ stay true: every ```python block runs, every shown output is what the code
prints, and every link resolves.

Blocks of one file run in order in one namespace, like a reader pasting them into a session.
Links must stay inside the repository (or be http(s)/mailto, which are not fetched) and reach an
existing file and, for ``page.md#anchor``, an existing heading.

Shown outputs (the convention, also in docs/architecture.md):

- a ```text block directly after a ```python block (nothing between them but blank lines and
  an ``<!-- output: … -->`` comment) is what that block prints to stdout;
- a ```text block directly after a ```bash block of ``chaplygin …`` commands is what those
  commands print on stdout (each must succeed); they run in-process through typer's test
  runner, in an empty working directory, 80 columns wide;
- the comparison ignores how much white space there is (not where), reads numbers as numbers
  (relative tolerance 1e-6 by default; ``<!-- output: rtol=1e-3 atol=1e-9 -->`` above the block
  states another), and takes ``...`` in a shown output for any text (a time, a temporary path);
- ``<!-- output: none: REASON -->`` above a ```text block that directly follows a code block says
  that it is not that block's output; a ```text block after prose is an illustration (a
  formula, a signature) and is not compared, but may not repeat what a block above printed.

``CHAPLYGIN_UPDATE_DOCS=1 python -m pytest tests/test_docs.py`` rewrites every shown output that
differs from what the code prints, in place and atomically: a shown line that still matches is
kept as it is (its ``...`` and its rounding too), every other line is replaced by the printed one.
"""

from __future__ import annotations

import difflib
import html
import math
import os
import re
import shlex
import tempfile
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
#: a shown output is compared with what the code prints to this relative precision by default
DEFAULT_RTOL = 1e-6
#: set to rewrite the shown outputs from what the code prints
UPDATE = os.environ.get("CHAPLYGIN_UPDATE_DOCS", "") not in ("", "0")

# ---------------------------------------------------------------- blocks of a page
FENCE_OPEN = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})\s*(?P<lang>[\w+-]*)")
MARKER = re.compile(r"^\s*<!--\s*output:\s*(?P<spec>.*?)\s*-->\s*$")
SHELL = {"bash", "sh", "shell", "console"}


@dataclass
class Block:
    """A fenced block of a page: its language, its text, where it sits."""

    lang: str
    text: str
    opening: int  #: index of the opening fence line (0-based)
    closing: int  #: index of the closing fence line
    #: the code block this one directly follows (only blank lines and markers between), or None
    after: Block | None = None
    #: the ``<!-- output: … -->`` specs between that block and this one
    markers: list[str] = field(default_factory=list)

    @property
    def line(self) -> int:
        """The 1-based line of the opening fence."""
        return self.opening + 1


def blocks(text: str) -> list[Block]:
    """The fenced blocks of a Markdown text, in order, each linked to the block it follows."""
    lines = text.splitlines()
    found: list[Block] = []
    k, gap_clean, markers = 0, False, []
    while k < len(lines):
        opening = FENCE_OPEN.match(lines[k])
        if not opening:
            marker = MARKER.match(lines[k])
            if marker:
                markers.append(marker.group("spec"))
            elif lines[k].strip():
                gap_clean, markers = False, []
            k += 1
            continue
        fence, indent = opening.group("fence"), len(opening.group("indent"))
        end = k + 1
        while end < len(lines) and not re.fullmatch(rf"\s*{fence[0]}{{{len(fence)},}}\s*", lines[end]):
            end += 1
        body = "".join(line[indent:] + "\n" for line in lines[k + 1 : end])
        previous = found[-1] if found and gap_clean else None
        found.append(Block(opening.group("lang").lower(), body, k, end, previous, markers))
        k, gap_clean, markers = end + 1, True, []
    return found


@dataclass
class Output:
    """A shown output: the ```text block, the block whose output it shows, the precision."""

    block: Block
    source: Block
    rtol: float = DEFAULT_RTOL
    atol: float = 0.0


def outputs(page_blocks: list[Block], name: str = "") -> tuple[list[Output], list[tuple[Block, str]]]:
    """The shown outputs of a page, and the ```text blocks marked as no output (with the reason).

    Raises ``ValueError`` for a marker that is malformed or sits where it means nothing."""
    shown: list[Output] = []
    marked: list[tuple[Block, str]] = []
    for block in page_blocks:
        code = (
            block.after
            if block.lang == "text" and block.after and block.after.lang in {"python", *SHELL}
            else None
        )
        if not block.markers:
            if code is not None:
                shown.append(Output(block, code))
            continue
        where = f"{name}:{block.line}"
        if code is None or len(block.markers) > 1:
            raise ValueError(
                f"{where}: an <!-- output: --> comment belongs directly above one ```text block "
                "that directly follows a code block"
            )
        spec = block.markers[0]
        if spec.startswith("none"):
            reason = spec[len("none") :].lstrip(" :-–—")
            if not reason:
                raise ValueError(f"{where}: <!-- output: none: REASON --> needs a reason")
            marked.append((block, reason))
            continue
        output = Output(block, code)
        for item in spec.split():
            key, _, value = item.partition("=")
            if key not in ("rtol", "atol"):
                raise ValueError(
                    f"{where}: unknown output option {item!r}; use rtol=NUMBER, atol=NUMBER or none: REASON"
                )
            try:
                setattr(output, key, float(value))
            except ValueError:
                raise ValueError(f"{where}: {item!r}: {key} must be a number") from None
        shown.append(output)
    return shown, marked


# ---------------------------------------------------------------- comparison
NUMBER = r"(?<![\w.])-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])"
TOKEN = re.compile(rf"(?P<ellipsis>\.\.\.)|(?P<number>{NUMBER})|(?P<space>\s+)|(?P<other>.)", re.S)


def _normal(text: str) -> str:
    """The text in Unicode's composed form, without trailing white space on its lines and
    without blank lines around it."""
    text = unicodedata.normalize("NFC", text)  # ẋ as one character or as x and a combining dot
    return "\n".join(line.rstrip() for line in text.strip("\n").splitlines()).strip()


def _pattern(shown: str) -> tuple[re.Pattern[str], list[str]]:
    """A regular expression for what may be printed where ``shown`` is shown, and its numbers."""
    parts: list[str] = []
    numbers: list[str] = []
    for token in TOKEN.finditer(_normal(shown)):
        kind, value = token.lastgroup, token.group()
        if kind == "ellipsis":
            parts.append(".*?")
        elif kind == "number":
            parts.append(f"({NUMBER})")
            numbers.append(value)
        elif kind == "space":
            parts.append(r"\s+")
        else:
            parts.append(re.escape(value))
    return re.compile("".join(parts), re.S), numbers


def matches(shown: str, printed: str, rtol: float = DEFAULT_RTOL, atol: float = 0.0) -> bool:
    """Whether ``printed`` is what ``shown`` shows: the same text up to the amount of white space,
    ``...`` standing for any text, numbers equal within ``rtol``/``atol`` (integers exactly)."""
    pattern, numbers = _pattern(shown)
    found = pattern.fullmatch(_normal(printed))
    if found is None:
        return False
    for a, b in zip(numbers, found.groups()):
        if re.fullmatch(r"-?\d+", a) and re.fullmatch(r"-?\d+", b):
            if int(a) != int(b):
                return False
        elif not math.isclose(float(a), float(b), rel_tol=rtol, abs_tol=atol):
            return False
    return True


def updated(shown: str, printed: str, rtol: float = DEFAULT_RTOL, atol: float = 0.0) -> str:
    """``printed`` as a shown output: each printed line that a shown line still matches keeps the
    shown line (its ``...``, its rounding); the others are the printed lines."""
    old, new = _normal(shown).splitlines(), _normal(printed).splitlines()
    # longest common subsequence under `matches`, line by line
    best = [[0] * (len(new) + 1) for _ in range(len(old) + 1)]
    for i in range(len(old) - 1, -1, -1):
        for j in range(len(new) - 1, -1, -1):
            same = matches(old[i], new[j], rtol, atol) if old[i].strip() or not new[j].strip() else False
            best[i][j] = best[i + 1][j + 1] + 1 if same else max(best[i + 1][j], best[i][j + 1])
    lines, i, j = [], 0, 0
    while j < len(new):
        if i < len(old) and best[i][j] == best[i + 1][j + 1] + 1 and matches(old[i], new[j], rtol, atol):
            lines.append(old[i])
            i, j = i + 1, j + 1
        elif i < len(old) and best[i + 1][j] >= best[i][j + 1]:
            i += 1
        else:
            lines.append(new[j])
            j += 1
    return "\n".join(lines) + "\n"


def _diff(shown: str, printed: str, where: str) -> str:
    return "\n".join(
        difflib.unified_diff(
            _normal(shown).splitlines(),
            _normal(printed).splitlines(),
            f"{where} (shown)",
            "printed",
            lineterm="",
        )
    )


# ---------------------------------------------------------------- running a page
def cli_commands(block: Block) -> list[list[str]] | None:
    """The argument lists of a shell block's ``chaplygin …`` commands, or None if it has another."""
    commands = []
    for line in block.text.replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        if not words:
            continue
        if words[0] != "chaplygin":
            return None
        commands.append(words[1:])
    return commands or None


def run_cli(block: Block, where: str) -> str:
    """What the ``chaplygin`` commands of a shell block print on stdout, run in-process; each must
    succeed (stderr, with its progress and notes that depend on the caches, is not compared)."""
    from typer.testing import CliRunner

    from chaplygin.apps.cli import app

    commands = cli_commands(block)
    if commands is None:
        raise AssertionError(
            f"{where}: a shell block shown with its output may hold only `chaplygin …` commands"
        )
    printed = []
    for args in commands:
        result = CliRunner().invoke(app, args)
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            raise result.exception
        assert result.exit_code == 0, (
            f"{where}: chaplygin {shlex.join(args)}: exit {result.exit_code}\n{result.stderr}"
        )
        printed.append(result.stdout)
    return "".join(printed)


def _write_atomically(path: Path, text: str) -> None:
    with tempfile.NamedTemporaryFile(
        "w", encoding="utf-8", dir=path.parent, delete=False, suffix=".tmp"
    ) as f:
        f.write(text)
    os.replace(f.name, path)


def _squeezed(text: str) -> str:
    return " ".join(text.split())


def check_page(
    page: Path, capsys: pytest.CaptureFixture[str], name: str, *, update: bool = False
) -> list[str]:
    """Run a page's blocks in order in one namespace and compare each shown output with what its
    block printed; the failures, each a unified diff naming the page and the line. With
    ``update``, every differing output is rewritten in the page instead (the page is written once,
    atomically; the prose, the code and the markers are left as they are)."""
    text = page.read_text(encoding="utf-8")
    page_blocks = blocks(text)
    shown, _ = outputs(page_blocks, name)
    sources = {id(output.source) for output in shown}
    namespace: dict[str, object] = {"__name__": "__docs__"}
    printed: dict[int, str] = {}
    for block in page_blocks:
        if block.lang == "python":
            capsys.readouterr()
            exec(compile(block.text, f"{name}:{block.line}", "exec"), namespace)
            printed[id(block)] = capsys.readouterr().out
        elif block.lang in SHELL and id(block) in sources:
            printed[id(block)] = run_cli(block, f"{name}:{block.line}")
    failures: list[str] = []
    lines = text.splitlines(keepends=True)
    for output in reversed(shown):  # from the end, so that a rewrite keeps the lines above in place
        got = printed[id(output.source)]
        if matches(output.block.text, got, output.rtol, output.atol):
            continue
        where = f"{name}:{output.block.line}"
        failures.insert(
            0,
            f"{where}: the output of the block at line {output.source.line}\n"
            + _diff(output.block.text, got, where),
        )
        new = updated(output.block.text, got, output.rtol, output.atol)
        if not matches(new, got, output.rtol, output.atol):  # a kept `...` took too much: all printed
            new = _normal(got) + "\n"
        lines[output.block.opening + 1 : output.block.closing] = [new]
    if update and failures:
        _write_atomically(page, "".join(lines))
        failures = []
    everything = _squeezed("".join(printed.values()))
    illustrations = [b for b in page_blocks if b.lang == "text" and all(b is not o.block for o in shown)]
    for block in illustrations:  # an illustration that repeats a printed output is an output
        if len(_squeezed(block.text)) > 20 and _squeezed(block.text) in everything:
            failures.append(
                f"{name}:{block.line}: this ```text block after prose shows what a block above prints: "
                "put it directly after that block"
            )
    return failures


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_code_blocks_run_and_print_what_is_shown(
    page: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Every ```python block runs; every shown output is what its block prints."""
    monkeypatch.chdir(tmp_path)  # files a page writes by a relative name land here
    monkeypatch.setenv("COLUMNS", "80")  # what wraps to the terminal's width wraps as when piped
    failures = check_page(page, capsys, str(page.relative_to(ROOT)), update=UPDATE)
    assert not failures, (
        "shown outputs differ from what the code prints (CHAPLYGIN_UPDATE_DOCS=1 rewrites them):\n\n"
        + "\n\n".join(failures)
    )


def test_shown_outputs_are_checked() -> None:
    """Every ```text block directly after a code block is checked, or marked with a reason; the
    count keeps a change of the convention from silently dropping the checks."""
    checked, marked = 0, []
    for page in PAGES:
        shown, none = outputs(blocks(page.read_text(encoding="utf-8")), str(page.relative_to(ROOT)))
        checked += len(shown)
        marked += [f"{page.relative_to(ROOT)}:{b.line}: {why}" for b, why in none]
        for output in shown:
            if output.source.lang in SHELL:
                assert cli_commands(output.source), f"{page}:{output.source.line}: not a chaplygin command"
    print(f"{checked} shown outputs checked; {len(marked)} marked as no output:", *marked, sep="\n")
    assert (
        checked >= 81
    )  # 81 when this check was written: 76 after ```python blocks, 5 after chaplygin commands
    assert len(marked) <= 5


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


# ---------------------------------------------------------------- the output checker itself
@pytest.mark.parametrize(
    ("shown", "printed", "options", "same"),
    [
        # white space: how much, not where; trailing spaces and blank lines around do not count
        ("a  b\n\n", "\na b   \n", {}, True),
        ("a b", "ab", {}, False),
        # ẋ as one character (U+1E8B) and as x + a combining dot (U+0307), as SymPy prints it
        ("\u1e8b = 0", "x\u0307 = 0", {}, True),
        # numbers: within the relative tolerance, integers exactly; digits in names are text
        ("x = 0.3", "x = 0.30000000000000004", {}, True),
        ("x = 0.3", "x = 0.3001", {}, False),
        ("x = 0.3", "x = 0.3001", {"rtol": 1e-3}, True),
        ("drift 1.2e-10", "drift 3.4e-11", {}, False),
        ("drift 1.2e-10", "drift 3.4e-11", {"atol": 1e-9}, True),
        ("eq. (28)", "eq. (29)", {"rtol": 0.5}, False),
        ("mu_1 = 0", "mu_2 = 0", {"rtol": 1}, False),
        ("x = -1", "x = 1", {"rtol": 1}, False),
        # `...` stands for any text, also over lines; the rest must still be there
        ("took ... s -> .../k.parquet", "took 0.05 s -> /tmp/tmpab/k.parquet", {}, True),
        ("a\n...\nd", "a\nb\nc\nd", {}, True),
        ("took ... s", "took 0.05 min", {}, False),
    ],
)
def test_matches(shown: str, printed: str, options: dict[str, float], same: bool) -> None:
    assert matches(shown, printed, **options) is same


def test_updated_keeps_what_still_matches() -> None:
    shown = "run ... s\nx = 0.3\nold line\nend\n"
    printed = "run 1.5 s\nx = 0.30000000000000004\nnew line\nanother\nend\n"
    assert updated(shown, printed) == "run ... s\nx = 0.3\nnew line\nanother\nend\n"


def test_outputs_follow_the_convention() -> None:
    page = "\n".join(
        [
            "# Page",  # 1
            "```python",  # 2
            "print(1)",
            "```",
            "",
            "<!-- output: rtol=1e-3 atol=1e-9 -->",  # 6
            "```text",  # 7: the output of line 2, with its precision
            "1",
            "```",
            "Prose.",
            "```text",  # 11: after prose, an illustration
            "E = T + U",
            "```",
            "```bash",  # 14
            "chaplygin models   # a comment",
            "```",
            "```text",  # 17: the output of the chaplygin command at line 14
            "...",
            "```",
            "```python",  # 20
            "x = 1",
            "```",
            "<!-- output: none: the file it reads, not an output -->",
            "```text",  # 24: marked
            "x = 1",
            "```",
        ]
    )
    shown, marked = outputs(blocks(page), "page.md")
    assert [(o.block.line, o.source.line, o.rtol, o.atol) for o in shown] == [
        (7, 2, 1e-3, 1e-9),
        (17, 14, DEFAULT_RTOL, 0.0),
    ]
    assert [(b.line, why) for b, why in marked] == [(24, "the file it reads, not an output")]
    assert cli_commands(shown[1].source) == [["models"]]
    for wrong in (
        "Prose.\n<!-- output: rtol=1e-3 -->\n```text\nE\n```\n",  # after prose: means nothing
        "```python\n```\n<!-- output: none -->\n```text\nx\n```\n",  # no reason
        "```python\n```\n<!-- output: tol=1 -->\n```text\nx\n```\n",  # unknown option
    ):
        with pytest.raises(ValueError, match="page.md:"):
            outputs(blocks(wrong), "page.md")


def test_a_drifted_output_is_reported_and_rewritten(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A page whose shown output is not what its block prints fails with a diff that names the
    page and the line; the update rewrites only that output, and the page then passes."""
    monkeypatch.chdir(tmp_path)
    page = tmp_path / "page.md"
    text = (
        "# A page\n\n```python\nprint('x =', 0.1 + 0.2)\nprint('took 1.5 s')\n```\n\n"  # lines 1-7
        "```text\nx = 0.3\ntook ... s\n```\n\nSome prose.\n\n"  # 8-14: right
        "```python\nprint('two')\n```\n\n```text\nthree\n```\n\n"  # 15-17, 19-21: wrong
        "```bash\nchaplygin examples show knife-edge\n```\n\n"  # 23-25
        "```text\n# chaplygin system file: ...\n...\nphi = 0.0\n...\n```\n"  # 27: right
    )
    page.write_text(text, encoding="utf-8")
    failures = check_page(page, capsys, "page.md")
    assert len(failures) == 1
    assert failures[0].startswith("page.md:19: the output of the block at line 15\n")
    assert "\n-three\n+two" in failures[0]
    assert check_page(page, capsys, "page.md", update=True) == []
    assert page.read_text(encoding="utf-8") == text.replace("three", "two")
    assert check_page(page, capsys, "page.md") == []
    page.write_text(
        "```python\nprint('a line printed by the block')\n```\n\nProse.\n\n```text\na line printed by the block\n```\n"
    )
    (failure,) = check_page(page, capsys, "page.md")
    assert failure.startswith("page.md:7: this ```text block after prose shows what a block above prints")
