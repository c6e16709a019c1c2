"""Long expressions broken into lines, and folded into a summary: one rule for every display.

A rolling body's or a roller racer's equations run to tens of thousands of characters.  Printed
on one line they are unreadable, typeset on one line they are kilometres wide.  This module is
the one place that decides how a long expression is shown, for the terminal (``chaplygin
derive``, ``check``), ``str`` of a verdict, the notebook displays (``_repr_latex_``, ``_repr_html_``) and the
HTML report:

* An expression is cut into **pieces** (:func:`tokens`): subexpressions of at most
  :data:`PIECE_NODES` symbols and operations, printed whole by whichever printer the display
  uses, joined by the operators of the sums, products, fractions and powers above them.  A line
  may break before any ``+``, ``−``, ``=``, ``·`` or ``/`` of those, at any depth, so no line
  is wider than its widest piece (:func:`lines`; LaTeX in :func:`latex`).
* An expression of more than :data:`FOLD_NODES` symbols and operations (about a screen) is
  **folded**: shown as a summary, its size and its leading structure within
  :data:`~chaplygin.core._brief.MAX_BRIEF` characters, breadth first, with ``…`` for what is
  left out (:func:`summary`), and the whole of it one option (``--full``) or one click (HTML
  ``<details>``) away.

The pieces are printer-agnostic: a display prints each :class:`Token` with its own printer
(file syntax, LaTeX, MathML), so the rule is the same everywhere.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import sympy as sp

from chaplygin.core._brief import MAX_BRIEF
from chaplygin.core._symbols import _small, file_syntax

__all__ = [
    "FOLD_NODES",
    "LINE_WIDTH",
    "PIECE_NODES",
    "PRETTY_WIDTH",
    "Token",
    "abbreviated",
    "folded",
    "html",
    "html_math",
    "latex",
    "lines",
    "note",
    "pretty",
    "size",
    "summary",
    "text",
    "tokens",
]

#: an expression of more symbols and operations than this (about 2 000-2 500 characters, a
#: screen) is folded into a summary
FOLD_NODES = 1000
#: the largest subexpression printed whole as one piece (about 60 characters)
PIECE_NODES = 24
#: characters of text per line of a broken expression
LINE_WIDTH = 80


def size(expr: sp.Basic, limit: float = float("inf")) -> int:
    """The symbols and operations of ``expr`` (its tree's nodes), counted up to just past ``limit``."""
    count, stack = 0, [expr]
    while stack and count <= limit:
        count += 1
        stack.extend(stack.pop().args)
    return count


def folded(expr: sp.Basic) -> bool:
    """Whether a display folds ``expr``: more than :data:`FOLD_NODES` symbols and operations."""
    return size(expr, FOLD_NODES) > FOLD_NODES


def note(expr: sp.Basic) -> str:
    """What a folded expression is: ``"a sum of 7 terms, 10 838 symbols and operations"``."""
    n = f"{size(expr):,}".replace(",", " ")
    body = expr.lhs if isinstance(expr, sp.Equality) and expr.rhs == 0 else expr
    what = f"a sum of {len(body.args)} terms, " if isinstance(body, sp.Add) else ""
    return f"{what}{n} symbols and operations"


# ====================================================================== the tree of pieces
@dataclass(eq=False)
class _Node:
    """``expr`` cut for display: a piece (``kind == "piece"``), or an operation on the nodes of
    its ``parts`` (built when first asked for: a summary looks at the top of a tree only)."""

    kind: str  # piece, sum, product, fraction, power, equation
    expr: sp.Basic
    parts: list[tuple[sp.Basic, bool]] = field(default_factory=list)  # (expression, a piece as it is)
    ordered: bool = True  # sums in SymPy's display order (as file_syntax prints them)
    signs: list[str] = field(default_factory=list)  # sum: "+" or "-" before each term
    negative: bool = False  # product, fraction: a leading minus
    exponent: sp.Basic | None = None  # power

    @cached_property
    def children(self) -> list[_Node]:
        return [_Node("piece", e) if whole else _build(e, self.ordered) for e, whole in self.parts]


def _is_sum(node: _Node) -> bool:
    return node.kind == "sum" or (node.kind == "piece" and isinstance(node.expr, sp.Add))


def _build(expr: sp.Basic, ordered: bool | None = None) -> _Node:
    if ordered is None:  # as file_syntax orders the terms: up to ORDERED_NODES, on the DAG
        ordered = _small(expr)
    if isinstance(expr, sp.Equality):
        return _Node("equation", expr, [(expr.lhs, False), (expr.rhs, False)], ordered)
    if size(expr, PIECE_NODES) <= PIECE_NODES:
        return _Node("piece", expr)
    if isinstance(expr, sp.Add):
        terms = expr.as_ordered_terms() if ordered else list(expr.args)
        signs = ["-" if term.could_extract_minus_sign() else "+" for term in terms]
        parts = [(-term if sign == "-" else term, False) for term, sign in zip(terms, signs)]
        return _Node("sum", expr, parts, ordered, signs)
    if isinstance(expr, sp.Mul):
        negative = expr.could_extract_minus_sign()
        body = -expr if negative else expr
        numer, denom = sp.fraction(body)
        if denom != 1:
            return _Node("fraction", expr, [(numer, False), (denom, False)], ordered, negative=negative)
        if not isinstance(body, sp.Mul):
            return _Node("product", expr, [(body, False)], ordered, negative=negative)
        parts, run = [], []  # in the printed order, each run of small factors one piece
        for f in body.as_ordered_factors() if ordered else body.args:
            if size(f, PIECE_NODES) <= PIECE_NODES and not isinstance(f, sp.Add):
                run.append(f)
                continue
            if run:
                parts.append((sp.Mul(*run), True))
                run = []
            parts.append((f, False))
        if run:
            parts.append((sp.Mul(*run), True))
        return _Node("product", expr, parts, ordered, negative=negative)
    if isinstance(expr, sp.Pow) and expr.exp.is_number and expr.exp.is_negative:
        parts = [(sp.S.One, True), (sp.Pow(expr.base, -expr.exp), False)]
        return _Node("fraction", expr, parts, ordered)
    if isinstance(expr, sp.Pow) and size(expr.exp, PIECE_NODES) <= PIECE_NODES:
        return _Node("power", expr, [(expr.base, False)], ordered, exponent=expr.exp)
    return _Node("piece", expr)  # a function of a long argument, …: printed whole


# ====================================================================== tokens
@dataclass(frozen=True)
class Token:
    """One item of a displayed expression, for a printer to print.

    ``kind`` is ``"piece"`` (``expr``, printed whole), ``"op"`` (``text`` is ``+``, ``-``,
    ``=``, ``*`` or ``/``; ``prefix`` for a leading minus), ``"open"``, ``"close"`` (a
    parenthesis; a closing one may carry a power's ``expr`` as exponent) or ``"more"`` (what a
    summary leaves out, ``…``).  A line may break before a token with ``breaks``.
    """

    kind: str
    text: str = ""
    expr: sp.Basic | None = None
    breaks: bool = False
    prefix: bool = False


_MORE = Token("more", "…")


class _Plan:
    """Which nodes a summary shows: expanded nodes, and how many terms of each sum."""

    def __init__(self) -> None:
        self.shown: dict[int, int] = {}

    def expanded(self, node: _Node) -> bool:
        return id(node) in self.shown


def _emit(node: _Node, out: list[Token], plan: _Plan | None) -> None:
    if node.kind == "piece":
        out.append(Token("piece", expr=node.expr))
        return
    if plan is not None and not plan.expanded(node):
        out.append(_MORE)
        return
    if node.kind == "equation":
        _emit(node.children[0], out, plan)
        out.append(Token("op", "=", breaks=True))
        _emit(node.children[1], out, plan)
    elif node.kind == "sum":
        count = len(node.children) if plan is None else plan.shown[id(node)]
        for i, (sign, child) in enumerate(zip(node.signs[:count], node.children[:count])):
            if i or sign == "-":
                out.append(Token("op", sign, breaks=bool(i), prefix=not i))
            _emit(child, out, plan)
        if count < len(node.children):
            out += [Token("op", "+", breaks=True), _MORE]
    elif node.kind == "product":
        if node.negative:
            out.append(Token("op", "-", prefix=True))
        for i, child in enumerate(node.children):
            if i:
                out.append(Token("op", "*", breaks=True))
            _grouped(child, out, plan, _is_sum(child))
    elif node.kind == "fraction":
        if node.negative:
            out.append(Token("op", "-", prefix=True))
        numer, denom = node.children
        _grouped(numer, out, plan, _is_sum(numer))
        out.append(Token("op", "/", breaks=True))
        _grouped(denom, out, plan, not (denom.kind == "piece" and denom.expr.is_Atom))
    elif node.kind == "power":
        out.append(Token("open", "("))
        _emit(node.children[0], out, plan)
        out.append(Token("close", ")", expr=node.exponent))


def _grouped(node: _Node, out: list[Token], plan: _Plan | None, parenthesized: bool) -> None:
    if parenthesized:
        out.append(Token("open", "("))
    _emit(node, out, plan)
    if parenthesized:
        out.append(Token("close", ")"))


def tokens(expr: sp.Basic) -> list[Token]:
    """The whole of ``expr`` as pieces and the operators between them."""
    out: list[Token] = []
    _emit(_build(expr), out, None)
    return out


def _width(token: Token, cache: dict[int, int]) -> int:
    if token.kind == "piece":
        key = id(token.expr)
        if key not in cache:
            cache[key] = len(file_syntax(token.expr))
        return cache[key]
    if token.kind == "close" and token.expr is not None:
        return 3 + len(file_syntax(token.expr))
    return 3 if token.kind == "op" and not token.prefix and token.text in "+-=" else 1


def summary(expr: sp.Basic, width: int = MAX_BRIEF) -> list[Token]:
    """``expr`` shown within about ``width`` characters: the nodes nearest the top first
    (breadth first), the terms of a sum left to right, ``…`` for what does not fit."""
    root, plan = _build(expr), _Plan()
    cache: dict[int, int] = {}

    def cost(node: _Node) -> int:  # a node as a summary shows it before it is expanded
        if node.kind == "piece":
            return _width(Token("piece", expr=node.expr), cache) + 2 * isinstance(node.expr, sp.Add)
        return 1 + 2 * _is_sum(node)

    used, queue = cost(root), deque([(root, 0)])
    later: list[tuple[_Node, int]] = []  # sums that would show only "(… + …)": after the rest
    while queue or later:
        if not queue:
            queue.extend((node, -1) for node, _ in later)  # depth -1: now they may
            later = []
        node, depth = queue.popleft()
        if node.kind == "piece":
            continue
        if node.kind == "sum":
            shown, extra = 0, 0
            for child in node.children:
                step = 3 + cost(child)
                if used - 1 + extra + step + 4 > width and shown:
                    break
                extra += step
                shown += 1
            if depth > 1 and all(c.kind != "piece" for c in node.children[:shown]):
                later.append((node, depth))
                continue
            if used - 1 + extra > width:
                continue
            used += extra - 1 + (4 if shown < len(node.children) else 0)
            plan.shown[id(node)] = shown
            queue.extend((c, abs(depth) + 1) for c in node.children[:shown])
            continue
        extra = sum(cost(c) + 1 for c in node.children) + 2 * (node.kind == "power")
        if depth and used - 1 + extra > width:
            continue
        used += extra - 1
        plan.shown[id(node)] = 1
        queue.extend((c, abs(depth) + 1) for c in node.children)
    out: list[Token] = []
    _emit(root, out, plan)
    return out


def lines(toks: Sequence[Token], width: int = LINE_WIDTH) -> list[list[Token]]:
    """``toks`` in lines of about ``width`` characters, broken before tokens that allow it; a
    last line of less than a tenth of ``width`` (``= 0``) stays on the line before."""
    cache: dict[int, int] = {}
    out: list[list[Token]] = [[]]
    used = 0
    for tok in toks:
        w = _width(tok, cache)
        if tok.breaks and out[-1] and used + w > width:
            out.append([])
            used = 0
        out[-1].append(tok)
        used += w
    if len(out) > 1 and used < width // 10:
        last = out.pop()
        out[-1] += last
    return out


# ====================================================================== printers
def _text_token(tok: Token, printer: Callable[[sp.Basic], str]) -> str:
    if tok.kind == "piece":
        assert tok.expr is not None
        return printer(tok.expr)
    if tok.kind == "close" and tok.expr is not None:
        exp = printer(tok.expr)
        plain = tok.expr.is_Symbol or (tok.expr.is_Integer and tok.expr > 0)
        return f")**{exp}" if plain else f")**({exp})"
    if tok.kind == "op":
        return tok.text if tok.prefix or tok.text in "*/" else f" {tok.text} "
    return tok.text


def text(
    expr: sp.Basic,
    *,
    full: bool = False,
    hint: str = "",
    printer: Callable[[sp.Basic], str] = file_syntax,
    width: int = MAX_BRIEF,
) -> str:
    """``expr`` as one line of text: whole where small or ``full``, else its :func:`summary`
    followed by ``    # folded: <its size>; <hint>``."""
    if full or not folded(expr):
        if isinstance(expr, sp.Equality):
            return f"{printer(expr.lhs)} = {printer(expr.rhs)}"
        return printer(expr)
    return f"{abbreviated(expr, printer, width)}    # folded: {note(expr)}" + (f"; {hint}" if hint else "")


def abbreviated(
    expr: sp.Basic, printer: Callable[[sp.Basic], str] = file_syntax, width: int = MAX_BRIEF
) -> str:
    """The :func:`summary` of ``expr`` as text, ``…`` for what it leaves out."""
    return "".join(_text_token(t, printer) for t in summary(expr, width))


def _latex_token(tok: Token, at_start: bool) -> str:
    from sympy.physics.vector.printing import vlatex

    if tok.kind == "piece":
        assert tok.expr is not None
        return vlatex(tok.expr)
    if tok.kind == "more":
        return r"\dots"
    if tok.kind == "close":
        return ")" if tok.expr is None else f")^{{{vlatex(tok.expr)}}}"
    if tok.kind == "op":
        if tok.text == "*":
            return r"\cdot " if at_start else r"\, "
        return tok.text if tok.prefix else f" {tok.text} "
    return tok.text


def _latex_line(line: Sequence[Token]) -> str:
    """A line of LaTeX: parentheses that open and close on it are ``\\left( \\right)``."""
    out = [_latex_token(t, i == 0) for i, t in enumerate(line)]
    stack: list[int] = []
    for i, tok in enumerate(line):
        if tok.kind == "open":
            stack.append(i)
        elif tok.kind == "close" and stack:
            out[stack.pop()] = r"\left("
            out[i] = r"\right" + out[i]
    return "".join(out).strip()


def _latex_lines(toks: Sequence[Token], width: int) -> list[str]:
    return [_latex_line(line) for line in lines(toks, width)]


def latex(exprs: Iterable[sp.Basic], *, full: bool = True, width: int = LINE_WIDTH) -> str:
    r"""The expressions (equations) as one LaTeX ``aligned`` block, each broken into lines of about
    ``width`` characters; a folded one (unless ``full``) as its summary and its size.

    An expression of at most ``2 * width`` characters of text stays on one line as SymPy
    typesets it (its fractions stacked, which takes about half the width of the text).  Where
    every expression does, the block is ``lhs &= rhs`` rows; otherwise every line starts at the
    left and the continuations are indented.
    """
    from sympy.physics.vector.printing import vlatex

    exprs = list(exprs)
    rows: list[list[str]] = []
    for e in exprs:
        if not full and folded(e):
            body = _latex_lines(summary(e), width)
            body[-1] += r"\quad\text{(folded: " + note(e) + ")}"
            rows.append(body)
        elif size(e, 4 * width) <= 4 * width and len(text(e, full=True)) <= 2 * width:
            rows.append([vlatex(e)])  # fits on a line as SymPy typesets it (fractions stacked)
        else:
            rows.append(_latex_lines(tokens(e), width))
    if all(len(r) == 1 for r in rows) and (full or not any(map(folded, exprs))):
        one = r" \\ ".join(rows[i][0] for i in range(len(exprs)))  # aligned at "="
        return r"\begin{aligned}" + one.replace("=", "&=") + r"\end{aligned}"
    out = [" \\\\\n".join(["& " + r[0], *(r"& \qquad " + line for line in r[1:])]) for r in rows]
    return "\\begin{aligned}\n" + " \\\\[0.5ex]\n".join(out) + "\n\\end{aligned}"


def html(exprs: Sequence[sp.Basic], *, escape: Callable[[str], str], heading: str = "") -> str:
    """The expressions as HTML with ``$$…$$`` LaTeX (MathJax in Jupyter): small ones as one
    :func:`latex` block, each folded one as its summary, and the whole of it broken into lines
    inside a ``<details>`` element, one click away."""
    if not any(map(folded, exprs)):
        return heading + "$$" + escape(r"\displaystyle " + latex(exprs)) + "$$"
    return heading + "".join(html_math(e, escape=escape, display=True) for e in exprs)


def html_math(expr: sp.Basic, *, escape: Callable[[str], str], display: bool = False) -> str:
    """One expression as HTML math (``$…$``, or ``$$…$$`` with ``display``); folded, its summary
    and the whole of it, broken into lines, in a ``<details>`` element."""
    from sympy.physics.vector.printing import vlatex

    fence = "$$" if display else "$"
    if not folded(expr):
        return fence + escape(latex([expr]) if display else vlatex(expr)) + fence
    return (
        f"{fence}{escape(latex([expr], full=False))}{fence}"
        f"<details><summary>the whole: {escape(note(expr))}</summary>$${escape(latex([expr]))}$$</details>"
    )


#: the widest Unicode rendering :func:`pretty` shows; a wider one is shown as text in lines
PRETTY_WIDTH = 4 * LINE_WIDTH


def pretty(exprs: Iterable[sp.Basic], *, full: bool = False, hint: str = "") -> list[str]:
    """Each expression for a Unicode display: as :func:`chaplygin.core._symbols.pretty` prints
    it where that is at most :data:`PRETTY_WIDTH` wide, else in the file syntax broken into lines
    of :data:`LINE_WIDTH` (:func:`lines`); folded as the one line of :func:`text` unless ``full``."""
    from chaplygin.core._symbols import pretty as whole

    out = []
    for e in exprs:
        if not full and folded(e):
            out.append(text(e, hint=hint))
            continue
        drawn = whole([e])
        if max(map(len, drawn.splitlines()), default=0) > PRETTY_WIDTH:
            rows = ["".join(_text_token(t, file_syntax) for t in line).strip() for line in lines(tokens(e))]
            drawn = "\n    ".join(rows)
        out.append(drawn)
    return out
