"""One self-contained HTML report per system.

:func:`write_report` writes a single HTML file, with no script and nothing fetched over the
network, that holds

* the system as given: coordinates, kinetic energy, V or U, forces, the constraints in both
  forms (A, eq. (1), and B, eq. (2)), parameters and initial state;
* the integrability verdict: conditions (28) and (33), the Frobenius test, finite relations;
* whether it is a Chaplygin system, and how the Chetaev and vakonomic models relate
  (:func:`~chaplygin.compare_models`);
* the equations of every model that applies, as MathML (rendered natively by browsers), a long
  one broken into lines and folded into a summary, the whole one click away;
* the models simulated from the same initial state: a summary table, figures as inline SVG,
  energy drift and constraint drift;
* for a rolling body (:func:`chaplygin.bodies.rolling_body`), the body drawn rolling in 3-D,
  the models side by side (:mod:`chaplygin.apps.bodyview`);
* with a steady motion (``chaplygin report --at``), its eigenvalues, named zero eigenvalues and
  verdict in each model, and a root locus (:mod:`chaplygin.apps._steady`);
* for the paper's sphere, the paper's printed equations (49)-(62) beside the derived ones,
  line by line: agree, differ by a transcription error, or differ in substance
  (:func:`paper_table`).

Math is rendered with SymPy's MathML presentation printer, extended to print time
derivatives of coordinates with dots and to set multi-letter names and functions apart by a thin
space in products.  Displayed formulas are rows of inline ``<math>`` pieces cut between terms
(:func:`mathml_pieces`), so that the browser wraps a long one as it wraps text.  A formula with a
term too wide for that is cut at every depth, into pieces of a few dozen symbols
(:mod:`chaplygin.core._fold`), and a formula beyond a screen is shown as its summary with the
whole of it one click away (``<details>``): the rule ``chaplygin derive`` and the notebook
displays fold by.
"""

from __future__ import annotations

import html
import io
import os
import re
import unicodedata
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from html.entities import html5 as _HTML5
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.printing.mathml import MathMLPresentationPrinter
from sympy.printing.precedence import PRECEDENCE

from chaplygin.core import _fold
from chaplygin.core._symbols import TIME
from chaplygin.errors import ChaplyginError
from chaplygin.models import registry

if TYPE_CHECKING:
    from chaplygin.core.system import System
    from chaplygin.numeric.comparison import Comparison

__all__ = [
    "GENERATOR",
    "STAGES",
    "VERDICTS",
    "PaperLine",
    "PaperTable",
    "applicable_models",
    "default_models",
    "is_paper_sphere",
    "mathml",
    "mathml_pieces",
    "paper_table",
    "render_report",
    "report_comparison",
    "write_report",
]

#: ``<meta name="generator">`` of every report; the demo recognises its own output by it.
GENERATOR = "chaplygin report"

#: The stages :func:`render_report` goes through, in order (for progress display).
STAGES = ("system", "integrability", "equations", "simulation", "figures", "paper")

#: Verdicts of :func:`paper_table`.
VERDICTS = ("agree", "transcription error", "differs in substance")


# ====================================================================== MathML
#: The space set beside a multi-letter name or a function in a product (LaTeX's ``\,``), so that
#: ``l² mp sin(2α)`` does not read ``l²mpsin(2α)``, a product of letters.
THIN_SPACE = "0.1667em"
_INVISIBLE_TIMES = "&InvisibleTimes;"


def _letters(node: Any) -> int:
    """The letters of an ``<mi>`` (combining marks such as the tilde of T̃ not counted), else 0."""
    if node.nodeType != node.ELEMENT_NODE or node.tagName != "mi":
        return 0
    text = "".join(c.data for c in node.childNodes if c.nodeType == c.TEXT_NODE)
    return sum(not unicodedata.combining(ch) for ch in text)


def _starts_word(node: Any) -> bool:
    """The box begins with an upright word: a multi-letter name, or a function (``sin(…)``)."""
    if _letters(node) > 1:
        return True
    if node.nodeType == node.ELEMENT_NODE and node.tagName in ("mrow", "msup", "msub", "msubsup", "mover"):
        return bool(node.childNodes) and _starts_word(node.firstChild)
    return False


def _ends_word(node: Any) -> bool:
    """The box ends with a multi-letter name (dotted or not)."""
    if _letters(node) > 1:
        return True
    if node.nodeType == node.ELEMENT_NODE and node.tagName in ("mrow", "mover"):
        return bool(node.childNodes) and _ends_word(
            node.firstChild if node.tagName == "mover" else node.lastChild
        )
    return False


class _Printer(MathMLPresentationPrinter):
    """SymPy's presentation MathML with ``q(t)`` printed as ``q`` and ``q̇``, ``q̈`` with dots, and
    a thin space beside multi-letter names and functions in products."""

    _DOTS: ClassVar[dict[int, str]] = {1: "\u02d9", 2: "\u00a8"}

    def _print_AppliedUndef(self, e: Any) -> Any:
        if e.args == (TIME,):
            return self._print(sp.Symbol(e.func.__name__))
        return self._print_Function(e)

    def _print_Mul(self, expr: Any) -> Any:
        mrow = self._coefficient_first(expr) or super()._print_Mul(expr)
        kids = list(mrow.childNodes)
        for before, op, after in zip(kids, kids[1:], kids[2:]):
            if (
                op.tagName == "mo"
                and op.firstChild is not None
                and op.firstChild.data == _INVISIBLE_TIMES
                and (_ends_word(before) or _starts_word(after))
            ):
                space = self.dom.createElement("mspace")
                space.setAttribute("width", THIN_SPACE)
                mrow.insertBefore(space, after)
        return mrow

    def _coefficient_first(self, expr: Any) -> Any:
        """``a(… + …)/5`` as ``(a/5)(… + …)``: the sum out of the fraction, where it can wrap;
        ``None`` unless the denominator is an integer and the numerator has a sum factor."""
        negative = expr.could_extract_minus_sign()
        numer, denom = sp.fraction(-expr if negative else expr)
        factors = sp.Mul.make_args(numer)
        sums = [f for f in factors if isinstance(f, sp.Add)]
        if not (denom.is_Integer and denom > 1 and sums):
            return None
        mrow = self.dom.createElement("mrow")
        if negative:
            minus = self.dom.createElement("mo")
            minus.appendChild(self.dom.createTextNode("-"))
            mrow.appendChild(minus)
        frac = self.dom.createElement("mfrac")
        frac.appendChild(self._print(sp.Mul(*[f for f in factors if not isinstance(f, sp.Add)])))
        frac.appendChild(self._print(denom))
        mrow.appendChild(frac)
        for term in sums:
            times = self.dom.createElement("mo")
            times.appendChild(self.dom.createTextNode(_INVISIBLE_TIMES))
            mrow.appendChild(times)
            mrow.appendChild(self.parenthesize(term, PRECEDENCE["Mul"]))
        return mrow

    @staticmethod
    def _dotted(e: Any) -> bool:
        return (
            isinstance(e, sp.Derivative)
            and isinstance(e.expr, AppliedUndef)
            and e.expr.args == (TIME,)
            and set(e.variables) == {TIME}
        )

    def parenthesize(self, item: Any, level: int, strict: bool = False) -> Any:
        if self._dotted(item):  # a dotted symbol is an atom, not a product d/dt · q
            return self._print(item)
        return super().parenthesize(item, level, strict)

    def _print_Derivative(self, e: Any) -> Any:
        if self._dotted(e):
            order = len(e.variables)
            base = self._print(e.expr)
            if order in self._DOTS:
                over = self.dom.createElement("mover")  # (accent="true" hides the dot of φ in Chromium)
                over.appendChild(base)
                dot = self.dom.createElement("mo")
                dot.appendChild(self.dom.createTextNode(self._DOTS[order]))
                over.appendChild(dot)
                return over
            sup = self.dom.createElement("msup")
            sup.appendChild(base)
            primes = self.dom.createElement("mo")
            primes.appendChild(self.dom.createTextNode("\u2032" * order))
            sup.appendChild(primes)
            return sup
        return super()._print_Derivative(e)


_ENTITY = re.compile(r"&([A-Za-z][A-Za-z0-9]*);")
_MINUS = re.compile(r"(<mo(?: [^>]*)?>)-</mo>")


def _plain_entities(text: str) -> str:
    """Named entities (``&InvisibleTimes;``) as characters, so the markup is also valid XML."""

    def repl(match: re.Match[str]) -> str:
        char = _HTML5.get(match.group(1) + ";")
        if char is None or char in "<>&\"'":
            return match.group(0)
        return char

    return _ENTITY.sub(repl, text)


def _as_basic(expr: Any, who: str) -> sp.Basic:
    if isinstance(expr, bool) or not isinstance(expr, (sp.Basic, int, float)):
        raise TypeError(f"{who}: expected a SymPy object or a number, got {type(expr).__name__}")
    if not isinstance(expr, sp.Basic):
        expr = sp.Integer(expr) if isinstance(expr, int) else sp.Float(expr)
    return expr


def _markup(nodes: Sequence[Any], *, display: str, displaystyle: bool = False) -> str:
    """One ``<math>`` element holding the printed ``nodes``."""
    body = "".join(node.toxml() for node in nodes).encode("ascii", "xmlcharrefreplace").decode()
    body = _MINUS.sub("\\1\u2212</mo>", _plain_entities(body))
    if len(nodes) > 1:
        body = f"<mrow>{body}</mrow>"
    style = ' displaystyle="true"' if displaystyle else ""
    return f'<math xmlns="http://www.w3.org/1998/Math/MathML" display="{display}"{style}>{body}</math>'


def mathml(expr: Any, *, display: str = "inline") -> str:
    """``<math>`` markup for a SymPy expression or equation, dots for time derivatives."""
    expr = _as_basic(expr, "mathml")
    return _markup([_Printer({"order": None})._print(expr)], display=display)


_BREAKS = ("+", "-", "=")


def _is_op(node: Any, ops: Sequence[str]) -> bool:
    return node.tagName == "mo" and node.firstChild is not None and node.firstChild.data in ops


def _is_sum(node: Any) -> bool:
    """An ``<mrow>`` of terms between ``+``, ``−`` or ``=``: a printed sum or equation."""
    kids = node.childNodes
    return (
        node.tagName == "mrow"
        and len(kids) >= 3
        and len(kids) % 2 == 1
        and all(_is_op(k, _BREAKS) == (i % 2 == 1) for i, k in enumerate(kids))
    )


def _parenthesized_sum(node: Any) -> Any:
    """The sum inside ``node`` when it is ``( sum )``, else ``None``."""
    kids = node.childNodes
    if (
        node.tagName == "mrow"
        and len(kids) == 3
        and _is_op(kids[0], ("(",))
        and _is_op(kids[2], (")",))
        and _is_sum(kids[1])
    ):
        return kids[1]
    return None


def _tokens(node: Any) -> list[tuple[Any, bool]]:
    """``node`` as a flat row of ``(node, break before it)``: sums and equations are opened,
    and so are the sums in parentheses among the factors of a product (``m a² (… + …)``)."""
    if _is_sum(node):
        out: list[tuple[Any, bool]] = []
        for i, kid in enumerate(node.childNodes):
            out += [(kid, True)] if i % 2 else _tokens(kid)
        return out
    kids = list(node.childNodes) if node.tagName == "mrow" else []
    if not (any(_is_op(k, (_INVISIBLE_TIMES,)) for k in kids) and any(map(_parenthesized_sum, kids))):
        return [(node, False)]
    if _is_op(kids[0], ("-",)):  # the product's sign: it stays a prefix in a longer row
        kids[0].setAttribute("form", "prefix")
    out = []
    for kid in kids:
        inner = _parenthesized_sum(kid)
        out += (
            [(kid, False)]
            if inner is None
            else [(kid.firstChild, False), *_tokens(inner), (kid.lastChild, False)]
        )
    return out


def mathml_pieces(expr: Any) -> list[str]:
    """The expression as a row of inline ``<math>`` elements in display style, cut before each
    ``+``, ``−`` and ``=`` between terms (of the expression, of both sides of an equation, and
    of a sum in parentheses among the factors of a product), so that a browser wraps a long
    formula between terms as it wraps words.  The operator that begins a piece is marked
    ``form="infix"``: it keeps the spacing of a binary operator."""
    expr = _as_basic(expr, "mathml_pieces")
    pieces: list[list[Any]] = []
    for node, cut in _tokens(_Printer({"order": None})._print(expr)):
        if cut:
            node.setAttribute("form", "infix")
        if cut or not pieces:
            pieces.append([node])
        else:
            pieces[-1].append(node)
    return [_markup(p, display="inline", displaystyle=True) for p in pieces]


def _block(expr: Any) -> str:
    """A displayed formula: its pieces wrap between terms when wider than the page.

    A formula beyond a screen (:func:`chaplygin.core._fold.folded`) is shown as its summary,
    typeset, with the whole of it, cut into pieces of at most
    :data:`~chaplygin.core._fold.PIECE_NODES` symbols and operations between which the browser
    may break the line, one click away in a ``<details>`` element.  A formula of more than
    :data:`TYPESET_NODES` symbols and operations (a rolling body's equations run to hundreds of
    thousands) is typeset only as its summary: the whole would take minutes and megabytes.
    """
    expr = _as_basic(expr, "_block")
    if not _fold.folded(expr):
        pieces = mathml_pieces(expr)
        if max(len(_TAG.sub("", p)) for p in pieces) > WIDEST_PIECE:  # a long fraction, a power
            return f'<div class="eq long">{_typeset(_fold.tokens(expr))}</div>'
        return f'<div class="eq">{"<wbr>".join(pieces)}</div>'
    note = _fold.note(expr)
    shown = f'<div class="eq long">{_typeset(_fold.summary(expr))}</div>'
    if _fold.size(expr, TYPESET_NODES) > TYPESET_NODES:
        why = f"not typeset whole: {note}; chaplygin derive --full prints it"
        return shown + f'<p class="note">{_esc(why)}</p>'
    whole = f'<div class="eq long">{_typeset(_fold.tokens(expr))}</div>'
    return shown + f"<details><summary>the whole formula: {_esc(note)}</summary>{whole}</details>"


#: the largest formula (in symbols and operations) that :func:`_block` typesets whole
TYPESET_NODES = 50_000
#: the widest piece (characters of its text) of a formula cut between the terms of its sums
#: only; a formula with a wider one is cut at every depth (:func:`chaplygin.core._fold.tokens`)
WIDEST_PIECE = 120
_TAG = re.compile(r"<[^>]+>")


def _typeset(tokens: Sequence[_fold.Token]) -> str:
    """``tokens`` as a row of inline ``<math>`` elements in display style, cut before every
    token a line may break before (:func:`chaplygin.core._fold.lines`)."""
    printer = _Printer({"order": None})
    dom = printer.dom

    def mo(text: str) -> Any:
        node = dom.createElement("mo")
        node.appendChild(dom.createTextNode(text))
        return node

    pieces: list[list[Any]] = []
    for tok in tokens:
        if tok.kind == "piece":
            node = printer._print(tok.expr)
        elif tok.kind == "more":
            node = dom.createElement("mi")
            node.appendChild(dom.createTextNode("…"))
        elif tok.kind == "close" and tok.expr is not None:
            node = dom.createElement("msup")
            node.appendChild(mo(")"))
            node.appendChild(printer._print(tok.expr))
        elif tok.text == "*":
            node = mo("\u22c5")  # a product cut between its factors: a visible dot
        else:
            node = mo(tok.text)
        if tok.kind == "op" and not tok.prefix:
            node.setAttribute("form", "infix")
        if tok.breaks or not pieces:
            pieces.append([node])
        else:
            pieces[-1].append(node)
    return "<wbr>".join(_markup(p, display="inline", displaystyle=True) for p in pieces)


def _cell(expr: Any) -> str:
    """Math in a table cell: left-aligned, wrapping between terms when wider than the cell."""
    return f'<div class="eq cell">{"<wbr>".join(mathml_pieces(expr))}</div>'


def _esc(text: Any) -> str:
    """Escaped for text and for double-quoted attributes (apostrophes stay readable)."""
    return html.escape(str(text), quote=False).replace('"', "&quot;")


# ====================================================================== models
#: Every (model, form) a report may show, in the registry's order (the family in its
#: classic form: the new one adds nothing a reader of the report needs)
_ALL_MODELS: tuple[tuple[str, str], ...] = tuple(
    (m.name, form)
    for m in registry.MODELS.values()
    for form in m.forms
    if not (m.constants and form == "new")
)


def applicable_models(system: System) -> tuple[list[tuple[str, str]], dict[str, str]]:
    """The (model, form) pairs that apply to ``system``, and why the others do not.

    Voronets' equations are listed only for systems that are not Chaplygin systems:
    for a Chaplygin system they are Chaplygin's equations (15).
    """
    true = registry.true_motion(system)
    out: list[tuple[str, str]] = []
    reasons: dict[str, str] = {}
    for model, form in _ALL_MODELS:
        entry = registry.MODELS[model]
        why = entry.obstruction(system)
        if why is not None:
            reasons[model] = ("the vakonomic multipliers do not integrate: " if entry.family else "") + why
            continue
        if entry.reduced and entry.is_true_motion and model != true:
            reasons[model] = "a Chaplygin system: Voronets' equations are Chaplygin's (15)"
            continue
        out.append((model, form))
    return out, reasons


def default_models(system: System) -> list[str]:
    """The models a comparison runs by default: the true motion first, then Lindelöf's."""
    true = registry.true_motion(system)
    if registry.MODELS["lindelof"].obstruction(system) is None:
        return [true, "lindelof"]
    return [true, "chetaev"]


# ====================================================================== the paper's sphere
@dataclass
class PaperLine:
    """One printed equation of the paper's §4 beside the derived expression.

    Attributes
    ----------
    number : str
        The paper's equation number, ``"(49)"`` … ``"(62)"``.
    what : str
        What the line is.
    ocr : str
        The line as it stands in the OCR'd seed text (LaTeX).
    printed : sympy.Expr
        The printed line typed as it stands, errors included.
    restored : sympy.Expr or None
        The printed line with the marks lost or misread in transcription restored
        (``repairs``); ``None`` when nothing needs restoring.
    repairs : list of str
        Each restoration, in words.
    derived : sympy.Expr
        The expression chaplygin derives.
    verdict : str
        One of :data:`VERDICTS`: the printed line equals the derived one (``"agree"``), or the
        restored one does (``"transcription error"``), or neither (``"differs in substance"``).
    """

    number: str
    what: str
    ocr: str
    printed: sp.Expr
    restored: sp.Expr | None
    repairs: list[str]
    derived: sp.Expr
    verdict: str = ""

    def judge(self) -> str:
        """Compare printed, then restored, with derived; set and return :attr:`verdict`."""
        if _same(self.printed, self.derived):
            self.verdict = VERDICTS[0]
        elif self.restored is not None and _same(self.restored, self.derived):
            self.verdict = VERDICTS[1]
        else:
            self.verdict = VERDICTS[2]
        return self.verdict


def _same(a: sp.Expr, b: sp.Expr) -> bool:
    """``a − b`` vanishes identically (random numeric points first: a difference is cheap to see)."""
    diff = sp.expand(a - b)
    if diff == 0:
        return True
    atoms = sorted(diff.atoms(sp.Derivative), key=lambda e: -len(e.variables))
    atoms += sorted(diff.atoms(AppliedUndef), key=str) + sorted(diff.free_symbols - {TIME}, key=str)
    rng = np.random.default_rng(49)
    for _ in range(4):
        point = {x: sp.Float(v) for x, v in zip(atoms, rng.uniform(0.3, 1.3, size=len(atoms)))}
        value = complex(diff.xreplace(point).evalf())
        if abs(value) > 1e-9:
            return False
    # Polynomials in sines and cosines: exact in exponentials, without simplify's search.
    if sp.expand(diff.rewrite(sp.exp)) == 0:
        return True
    return sp.simplify(diff) == 0


@dataclass
class PaperTable:
    """The lines of :func:`paper_table` and the whole-set classification."""

    lines: list[PaperLine]
    sets: list[tuple[str, str, str]] = field(default_factory=list)  # (equations, reading, verdict)

    def counts(self) -> dict[str, int]:
        return {v: sum(line.verdict == v for line in self.lines) for v in VERDICTS}

    def summary(self) -> str:
        c = self.counts()
        return (
            f"the paper's printed (49)-(62): {c['agree']} agree, {c['transcription error']} "
            f"differ by a transcription error, {c['differs in substance']} differ in substance"
        )


def paper_table(classify_sets: bool = True) -> PaperTable:
    """The paper's printed equations (49)-(62), typed by hand, beside chaplygin's derivation.

    The printed forms are read from the OCR'd seed text with ``\\psi`` = ψ (precession),
    ``\\theta`` = θ (nutation), ``\\varphi`` = φ (spin).  Forces are those of the paper's
    (44)-(46): applied moments ``M_ψ, M_θ, M_φ`` on the angles and a horizontal force
    ``(V_1, V_2)`` on the centre; the OCR prints the moments as ``m_3^0`` and ``m_N^0``.

    With ``classify_sets``, each group of three equations of motion, restored and with the
    forces set to zero, is also given to :func:`chaplygin.classify`.
    """
    from chaplygin import examples
    from chaplygin.analysis.transitions import classify, compare_models

    free = examples.rolling_sphere()
    psi, theta, phi, x, y = free.coordinates
    m, a = free.parameter("m"), free.parameter("a")
    M_psi, M_theta, M_phi, V1, V2 = sp.symbols("M_psi M_theta M_phi V_1 V_2", real=True)
    m30, mN0 = sp.Symbol("m_3^0"), sp.Symbol("m_N^0")
    forced = examples.rolling_sphere(
        m, a, forces={"psi": M_psi, "theta": M_theta, "phi": M_phi, "x": V1, "y": V2}
    )

    d = lambda q: q.diff(TIME)  # noqa: E731
    dd = lambda q: q.diff(TIME, 2)  # noqa: E731
    s, c = sp.sin(theta), sp.cos(theta)
    sp_, cp = sp.sin(psi), sp.cos(psi)
    R = sp.Rational

    lagrange = free.equations("lindelof").residuals  # E_σ(T̃)
    chaplygin_free = free.equations("chaplygin").residuals
    # The forces enter only F of M·x = F: −Q̃_σ = −(F_forced − F_free).  (Displaying the forced
    # equations themselves would cost seconds of tidying for the same expressions.)
    minus_forces = [
        sp.expand(g - f)
        for f, g in zip(forced.equations("chaplygin").forcing, free.equations("chaplygin").forcing)
    ]
    chaplygin_forced = [e + q for e, q in zip(chaplygin_free, minus_forces)]
    lindelof_forced = [e + q for e, q in zip(lagrange, minus_forces)]
    defect = list(compare_models(free).defect.values())
    momenta = [free.kinetic_energy.diff(d(q)).subs(free.constraints) for q in (x, y)]

    # ---- the printed lines, as they stand, and restored
    p49 = R(2, 5) * m * a**2 * (d(psi) + d(phi) * c - d(theta) * s)
    r49 = R(2, 5) * m * a**2 * (dd(psi) + dd(phi) * c - d(theta) * d(phi) * s)
    p50 = m * a**2 * (R(7, 5) * dd(theta) + d(phi) ** 2 * s * c + R(2, 5) * d(phi) * s)
    r50 = m * a**2 * (R(7, 5) * dd(theta) - d(phi) ** 2 * s * c + R(2, 5) * d(phi) * d(psi) * s)
    p51 = (
        m
        * a**2
        * (
            d(phi) * s**2
            + 2 * d(theta) * s * c
            + R(2, 5) * d(psi)
            + R(2, 5) * d(phi) * c
            - R(2, 5) * d(theta) * s
        )
    )
    r51 = (
        m
        * a**2
        * (
            dd(phi) * s**2
            + 2 * d(theta) * d(phi) * s * c
            + R(2, 5) * dd(phi)
            + R(2, 5) * dd(psi) * c
            - R(2, 5) * d(theta) * d(psi) * s
        )
    )
    rep49 = ["second dots lost: ψ̈, φ̈ printed as ψ̇, φ̇", "factor φ̇ of θ̇ φ̇ sin θ lost"]
    rep50 = [
        "ψ̇ lost: its dot sits on “sin” (\\dot{\\sin})",
        "sign of φ̇² sin θ cos θ misprinted as +: the paper's own (61) = (50) + (58) holds only with −",
    ]
    rep51 = [
        "second dot lost: φ̈ sin²θ",
        "factor φ̇ lost in 2 θ̇ φ̇ sin θ cos θ",
        "ψ and φ interchanged, second dots lost: (2/5) φ̈ + (2/5) ψ̈ cos θ",
        "factor ψ̇ lost in (2/5) θ̇ ψ̇ sin θ",
    ]
    force_psi = ["m_3^0 is the applied moment M_ψ of (44)"]
    force_theta = ["m_N^0 is the applied moment M_θ of (45)", "θ printed for ψ in V₁ sin ψ − V₂ cos ψ"]
    force_phi = ["m_3^0 here is the applied moment M_φ of (46)", "θ printed for ψ in V₁ cos ψ + V₂ sin ψ"]
    f_theta_p, f_theta_r = -mN0 - a * (V1 * s - V2 * c), -M_theta - a * (V1 * sp_ - V2 * cp)
    f_phi_p, f_phi_r = -m30 + a * s * (V1 * c + V2 * s), -M_phi + a * s * (V1 * cp + V2 * sp_)

    def products(X: sp.Expr, Y: sp.Expr) -> sp.Expr:
        """``m a X · a Y − m a Y · a X`` as printed: unevaluated, so it does not collapse to 0."""
        first = sp.Mul(m, a, X, a, Y, evaluate=False)
        return sp.Add(first, sp.Mul(-1, m, a, Y, a, X, evaluate=False), evaluate=False)

    X_p, Y_p = d(theta) * s - d(phi) * s * c, d(theta) * c + d(phi) * s * s
    X_r, Y_r = d(theta) * sp_ - d(phi) * s * cp, d(theta) * cp + d(phi) * s * sp_
    p61 = R(7, 5) * m * a**2 * (dd(theta) + d(phi) * s) + f_theta_p
    r61 = R(7, 5) * m * a**2 * (dd(theta) + d(phi) * d(psi) * s) + f_theta_r
    p62 = (
        m
        * a**2
        * (
            d(phi) * s**2
            + R(2, 5) * d(psi)
            + R(2, 5) * d(phi) * c
            + d(theta) * s * c
            - R(7, 5) * d(theta) * s
        )
        + f_phi_p
    )
    r62 = (
        m
        * a**2
        * (
            dd(phi) * s**2
            + R(2, 5) * dd(phi)
            + R(2, 5) * dd(psi) * c
            + d(theta) * d(phi) * s * c
            - R(7, 5) * d(theta) * d(psi) * s
        )
        + f_phi_r
    )

    body50 = (
        r"ma^2 \left[\frac{7}{5}\ddot{\theta} + \dot{\varphi}^2 \sin \theta \cos \theta"
        r" + \frac{2}{5}\dot{\varphi} \dot{\sin} \theta \right]"
    )
    body51 = (
        r"ma^2 \left[\dot{\varphi} \sin^2 \theta + 2\dot{\theta} \sin \theta \cos \theta"
        r" + \frac{2}{5}\dot{\psi} + \frac{2}{5}\dot{\varphi} \cos \theta"
        r" - \frac{2}{5}\dot{\theta} \sin \theta \right]"
    )
    body49 = r"\frac{2}{5}ma^2 (\dot{\psi} + \dot{\varphi} \cos \theta - \dot{\theta} \sin \theta)"
    E = "Lagrange's operator on T̃ (48)"
    L = "Lindelöf's (geodesic) equation (22) with the reduced forces Q̃ of (44)-(46)"
    C = "Chaplygin's (true) equation (15) with the forces of (44)-(46)"
    W = "the non-holonomic term of (15) (the Lindelöf defect)"
    lines = [
        PaperLine("(49)", f"{E}, ψ", body49, p49, r49, rep49, lagrange[0]),
        PaperLine("(50)", f"{E}, θ", body50, p50, r50, rep50, lagrange[1]),
        PaperLine("(51)", f"{E}, φ", body51, p51, r51, rep51, lagrange[2]),
        PaperLine(
            "(52)",
            f"{L}, ψ",
            body49 + r" - m_3^0",
            p49 - m30,
            r49 - M_psi,
            rep49 + force_psi,
            lindelof_forced[0],
        ),
        PaperLine(
            "(53)",
            f"{L}, θ",
            body50 + r" - m_N^0 - a(V_1 \sin \theta - V_2 \cos \theta)",
            p50 + f_theta_p,
            r50 + f_theta_r,
            rep50 + force_theta,
            lindelof_forced[1],
        ),
        PaperLine(
            "(54)",
            f"{L}, φ",
            body51 + r" - m_3^0 + a \sin \theta (V_1 \cos \theta + V_2 \sin \theta)",
            p51 + f_phi_p,
            r51 + f_phi_r,
            rep51 + force_phi,
            lindelof_forced[2],
        ),
        PaperLine(
            "(55)",
            "∂T/∂ẋ = m ẋ with the constraint (41)",
            r"-ma(\dot{\theta} \sin \theta - \dot{\varphi} \sin \theta \cos \theta)",
            -m * a * X_p,
            m * a * X_r,
            [
                "θ printed for ψ in sin ψ, cos ψ",
                "leading sign misprinted: (41) gives m ẋ = m a (θ̇ sin ψ − φ̇ sin θ cos ψ), "
                "the sign the paper's (57) uses",
            ],
            momenta[0],
        ),
        PaperLine(
            "(56)",
            "∂T/∂ẏ = m ẏ with the constraint (42)",
            r"-ma(\dot{\theta} \cos \theta + \dot{\varphi} \sin \theta \sin \theta)",
            -m * a * Y_p,
            -m * a * Y_r,
            ["θ printed for ψ in cos ψ, sin ψ"],
            momenta[1],
        ),
        PaperLine(
            "(57)",
            f"{W}, σ = ψ",
            r"ma(\dot{\theta} \sin \theta - \dot{\varphi} \sin \theta \cos \theta)"
            r" a(\dot{\theta} \cos \theta + \dot{\varphi} \sin \theta \sin \theta)"
            r" - ma(\dot{\theta} \cos \theta + \dot{\varphi} \sin \theta \sin \theta)"
            r" a(\dot{\theta} \sin \theta - \dot{\varphi} \sin \theta \cos \theta)",
            products(X_p, Y_p),
            products(X_r, Y_r),
            ["θ printed for ψ (immaterial: the two products cancel)"],
            defect[0],
        ),
        PaperLine(
            "(58)",
            f"{W}, σ = θ",
            r"ma^2 \dot{\varphi} \sin \theta (\dot{\theta} + \dot{\varphi} \cos \theta)",
            m * a**2 * d(phi) * s * (d(theta) + d(phi) * c),
            m * a**2 * d(phi) * s * (d(psi) + d(phi) * c),
            ["θ̇ printed for ψ̇"],
            defect[1],
        ),
        PaperLine(
            "(59)",
            f"{W}, σ = φ",
            r"-ma^2 \dot{\theta} \sin \theta (\dot{\theta} + \dot{\varphi} \cos \theta)",
            -m * a**2 * d(theta) * s * (d(theta) + d(phi) * c),
            -m * a**2 * d(theta) * s * (d(psi) + d(phi) * c),
            ["θ̇ printed for ψ̇"],
            defect[2],
        ),
        PaperLine(
            "(60)",
            f"{C}, ψ",
            body49 + r" - m_3^0",
            p49 - m30,
            r49 - M_psi,
            rep49 + force_psi,
            chaplygin_forced[0],
        ),
        PaperLine(
            "(61)",
            f"{C}, θ",
            r"\frac{7}{5}ma^2 (\ddot{\theta} + \dot{\varphi} \sin \theta) - m_N^0"
            r" - a(V_1 \sin \theta - V_2 \cos \theta)",
            p61,
            r61,
            ["factor ψ̇ lost in φ̇ ψ̇ sin θ", *force_theta],
            chaplygin_forced[1],
        ),
        PaperLine(
            "(62)",
            f"{C}, φ",
            r"ma^2 \left[\dot{\varphi} \sin^2 \theta + \frac{2}{5}\dot{\psi}"
            r" + \frac{2}{5}\dot{\varphi} \cos \theta + \dot{\theta} \sin \theta \cos \theta"
            r" - \frac{7}{5}\dot{\theta} \sin \theta \right] - m_3^0"
            r" + a \sin \theta (V_1 \cos \theta + V_2 \sin \theta)",
            p62,
            r62,
            [
                "second dot lost: φ̈ sin²θ",
                "ψ and φ interchanged, second dots lost: (2/5) φ̈ + (2/5) ψ̈ cos θ",
                "factor φ̇ lost in θ̇ φ̇ sin θ cos θ",
                "factor ψ̇ lost in (7/5) θ̇ ψ̇ sin θ",
                *force_phi,
            ],
            chaplygin_forced[2],
        ),
    ]
    for line in lines:
        line.judge()
    table = PaperTable(lines)
    if classify_sets:
        unforced = {M_psi: 0, M_theta: 0, M_phi: 0, V1: 0, V2: 0, m30: 0, mN0: 0}
        for label, group in (("(52)-(54)", lines[3:6]), ("(60)-(62)", lines[11:14])):
            for reading in ("printed", "restored"):
                exprs = [getattr(line, reading).xreplace(unforced) for line in group]
                try:
                    verdict = str(classify(free, exprs))
                except ChaplyginError as exc:
                    verdict = f"not equations of motion of the sphere: {exc}"
                table.sets.append((label, reading, verdict))
    return table


def is_paper_sphere(system: System) -> bool:
    """True when ``system`` is the paper's sphere: same coordinates, kinetic energy (47) and
    constraints (41)-(42) as :func:`chaplygin.examples.rolling_sphere` (forces may differ)."""
    from chaplygin import examples

    names = [q.func.__name__ for q in system.coordinates]
    if names != ["psi", "theta", "phi", "x", "y"] or [_name(q) for q in system.dependent] != ["x", "y"]:
        return False
    ref = examples.rolling_sphere()
    rename: dict[sp.Basic, sp.Basic] = {
        p: ref.parameter(p.name) for p in system.parameters if p.name in ("m", "a")
    }
    rename.update(zip(system.coordinates, ref.coordinates))

    def same(u: sp.Expr, v: sp.Expr) -> bool:
        return _same(u.xreplace(rename), v)

    if not same(system.kinetic_energy, ref.kinetic_energy):
        return False
    ours = {k.xreplace(rename): v for k, v in system.constraints.items()}
    return all(same(ours[k], v) for k, v in ref.constraints.items())


# ====================================================================== inputs
@dataclass
class _Source:
    system: System
    parameters: dict[str, float]
    initial: dict[str, float]
    name: str
    source: str
    #: the values given exactly (``pi/6``), by key, where the number used is that value
    exact: dict[str, sp.Expr] = field(default_factory=dict)


def _source(obj: Any, parameters: Mapping[str, float] | None, initial: Mapping[str, float] | None) -> _Source:
    from chaplygin.core.system import System

    if isinstance(obj, System):
        return _Source(obj, dict(parameters or {}), dict(initial or {}), obj.name, "")
    system = getattr(obj, "system", None)
    if not isinstance(system, System):
        raise ChaplyginError(
            f"write_report: expected a System or a system file (chaplygin.io.files.SystemFile), "
            f"got {type(obj).__name__}."
        )
    given = {**(getattr(obj, "parameters", None) or {}), **(getattr(obj, "initial", None) or {})}
    params = {**(getattr(obj, "parameters", None) or {}), **(parameters or {})}
    start = {**(getattr(obj, "initial", None) or {}), **(initial or {})}
    used = {**params, **start}
    exact = {  # an override that replaced the file's number is shown as given
        k: v for k, v in (getattr(obj, "exact", None) or {}).items() if k in given and used.get(k) == given[k]
    }
    return _Source(
        system,
        params,
        start,
        getattr(obj, "name", "") or system.name,
        str(getattr(obj, "source", "") or ""),
        exact,
    )


# ====================================================================== figures
def _svg(fig: Any) -> str:
    """A matplotlib figure as inline ``<svg>`` markup (no XML prolog, deterministic ids)."""
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": "chaplygin", "svg.fonttype": "path"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    start = text.find("<svg")
    return text[start:] if start >= 0 else text


# ====================================================================== HTML
_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 72rem;
       margin: 2rem auto; padding: 0 1rem; line-height: 1.45; color: #1b1b1b; }
h1 { font-size: 1.6rem; } h2 { border-bottom: 1px solid #ccc; margin-top: 2.5rem; }
table { border-collapse: collapse; margin: 0.8rem 0; }
th, td { border: 1px solid #d0d0d0; padding: 0.3rem 0.55rem; vertical-align: top; text-align: left; }
th { background: #f3f3f3; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.eq { text-align: center; padding: 0.25rem 0; overflow-x: auto; overflow-y: hidden; }
.eq math { margin-block: 0.25em; }
.eq.cell { text-align: left; padding: 0.1rem 0; }
.eq.long { text-align: left; padding-left: 2em; text-indent: -2em; }
math { font-size: 1.08em; }
.figure { margin: 1rem 0; overflow-x: auto; }
.figure svg { max-width: 100%; height: auto; }
code, pre { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 0.85em; }
pre { background: #f7f7f7; padding: 0.6rem; overflow-x: auto; }
.verdict { font-weight: 600; }
td .verdict { white-space: nowrap; }
table.paper { width: 100%; table-layout: fixed; }
table.paper td { overflow-wrap: break-word; }
.agree { color: #17652b; } .transcription { color: #8a5a00; } .substance { color: #a8141c; }
.holds { color: #17652b; } .fails { color: #a8141c; }
.note { color: #555; font-size: 0.92em; }
.warning { color: #8a4b00; border-left: 3px solid #d08a00; padding-left: 0.5em; }
td.ocr code { white-space: pre-wrap; word-break: break-word; }
"""

_VERDICT_CLASS = {VERDICTS[0]: "agree", VERDICTS[1]: "transcription", VERDICTS[2]: "substance"}


def _name(q: Any) -> str:
    return q.func.__name__


def _value(src: _Source, key: str, number: float) -> str:
    """A parameter or initial value as given: ``π/6`` where the file wrote ``"pi/6"``."""
    return "".join(mathml_pieces(src.exact[key])) if key in src.exact else f"{number:.10g}"


def _system_section(src: _Source) -> str:
    s = src.system
    out = ['<section id="system"><h2>The system as given</h2>']
    if src.source:
        out.append(f"<p>Source: <code>{_esc(src.source)}</code></p>")
    coords = ", ".join(mathml(q) for q in s.coordinates)
    out.append(
        f"<p>Coordinates ({s.n}): {coords}; independent: "
        f"{', '.join(mathml(q) for q in s.independent)}; dependent: "
        f"{', '.join(mathml(q) for q in s.dependent) or 'none'} "
        f"(n = {s.n}, g = {s.g}, ε = {s.epsilon}).</p>"
    )
    out.append("<p>Kinetic energy:</p>" + _block(sp.Eq(sp.Symbol("T"), s.kinetic_energy, evaluate=False)))
    if s.potential_energy is not None:
        out.append(
            "<p>Potential energy:</p>" + _block(sp.Eq(sp.Symbol("V"), s.potential_energy, evaluate=False))
        )
    elif s.force_function != 0:
        out.append("<p>Force function:</p>" + _block(sp.Eq(sp.Symbol("U"), s.force_function, evaluate=False)))
    else:
        out.append("<p>No potential: V = U = 0.</p>")
    if s.forces:
        out.append("<p>Generalized forces:</p>")
        out += [_block(sp.Eq(sp.Symbol(f"Q_{_name(q)}"), f, evaluate=False)) for q, f in s.forces.items()]
    if s.is_nonlinear:
        out.append(_nonlinear_paragraph(s))
    else:
        kind = "affine" if s.is_affine else "homogeneous"
        out.append(
            f"<p>Constraints ({s.g}, linear, {kind}; given in form {s.constraint_form}), "
            "solved, form B (eq. (2)):</p>"
        )
    out += [_block(sp.Eq(k, v, evaluate=False)) for k, v in s.constraints.items()]
    out.append("<p>Implicit, form A (eq. (1)):</p>")
    out += [_block(sp.Eq(e, 0, evaluate=False)) for e in s.implicit_constraints]
    if s.holonomic:
        out.append(
            f"<p>Holonomic constraints ({len(s.holonomic)}; their time derivatives are the last "
            "constraints above):</p>"
        )
        out += [_block(sp.Eq(f, 0, evaluate=False)) for f in s.holonomic.values()]
    out.append(
        "<p>Reduced kinetic energy (the constraints substituted into T):</p>"
        + _block(sp.Eq(sp.Symbol("T̃"), s.reduced_kinetic_energy, evaluate=False))
    )
    if src.parameters or src.initial:
        out.append("<table><tr><th>parameter / initial value</th><th>value</th></tr>")
        out += [
            f'<tr><td>{mathml(sp.Symbol(k))}</td><td class="num">{_value(src, k, v)}</td></tr>'
            for k, v in src.parameters.items()
        ]
        for k, v in src.initial.items():
            label = mathml(sp.Function(k[:-1])(TIME).diff(TIME)) if k.endswith("'") else mathml(sp.Symbol(k))
            out.append(f'<tr><td>{label}(0)</td><td class="num">{_value(src, k, v)}</td></tr>')
        out.append("</table>")
    out.append("</section>")
    return "\n".join(out)


def _nonlinear_paragraph(s: System) -> str:
    """The constraints' heading for constraints nonlinear in the velocities: the branch, whether
    the constraint forces do work (the Chetaev power where they do), where φ is singular."""
    branch = "" if s._branch is None else f", branch {s._branch} of the implicit constraints"
    text = (
        f"<p>Constraints ({s.g}, <b>nonlinear in the velocities</b>{branch}; given in form "
        f"{s.constraint_form}). The virtual displacements obey the Appell–Chetaev condition "
        "Σ<sub>s</sub> ∂f<sub>β</sub>/∂q̇<sub>s</sub> δq<sub>s</sub> = 0, so the constraint forces do "
        "no virtual work; "
    )
    if s.is_affine:
        try:
            power = s.equations("chetaev").power()
        except ChaplyginError:
            power = None
        text += (
            "the constraints are not homogeneous of degree 1 in the velocities, so the constraint "
            "forces <b>do work</b> along the motion"
            + (
                ""
                if power is None
                else ": their power Σ<sub>s</sub> R<sub>s</sub> q̇<sub>s</sub> = " + mathml(power)
            )
            + ". "
        )
    else:
        text += "they are homogeneous of degree 1 in the velocities, so the constraint forces do no work. "
    if s.singular_set:
        text += (
            "Singular (no smooth solution for the dependent velocities) where "
            + " or ".join(mathml(sp.Eq(e, 0, evaluate=False)) for e in s.singular_set)
            + ". "
        )
    return text + "Solved for the dependent velocities:</p>"


def _condition_rows(cond: Any) -> str:
    cls = "" if cond.holds is None else "holds" if cond.holds else "fails"
    shown = cond.failures[:6]
    fails = "".join(f"<li>{_esc(label)} = {mathml(expr)}</li>" for label, expr in shown)
    if len(cond.failures) > len(shown):
        fails += f"<li>… and {len(cond.failures) - len(shown)} more</li>"
    return (
        f'<tr><td>{_esc(cond.name)}</td><td class="{cls}">{cond.verdict}</td>'
        f"<td>{'<ul>' + fails + '</ul>' if fails else ''}"
        f'<span class="note">{_esc(cond.note)}</span></td></tr>'
    )


def _integrability_section(system: System) -> tuple[str, str]:
    report = system.integrability()
    verdict = "integrable (holonomic)" if report.integrable else "not integrable (nonholonomic)"
    out = [
        '<section id="integrability"><h2>Integrability of the constraints</h2>',
        f'<p class="verdict {"holds" if report.integrable else "fails"}">The constraints are '
        f"{_esc(report.verdict)}</p>",
        "<table><tr><th>test</th><th>verdict</th><th>non-vanishing components</th></tr>",
        _condition_rows(report.condition_28),
        _condition_rows(report.condition_33),
        _condition_rows(report.frobenius),
        "</table>",
    ]
    if report.integrable:
        if report.relations:
            out.append("<p>Finite relations (each constant along every motion):</p>")
            out += [_block(r) for r in report.relations]
        else:
            out.append("<p>No finite relation was found in closed form.</p>")
    out.append("</section>")
    return "\n".join(out), verdict


def _models_section(system: System) -> tuple[str, str]:
    from chaplygin.analysis.transitions import compare_models

    out = ['<section id="models"><h2>Chaplygin system and the two models</h2>']
    if system.is_chaplygin:
        out.append(
            "<p>A <b>Chaplygin system</b>: T, U, the forces and the constraint coefficients B "
            "are free of the dependent coordinates.</p>"
        )
    else:
        out.append(
            "<p><b>Not a Chaplygin system</b>: " + _esc("; ".join(system.chaplygin_obstructions)) + ".</p>"
        )
    try:
        comparison = compare_models(system)
    except ChaplyginError as exc:
        out.append(f'<p class="note">No Lindelöf comparison: {_esc(exc)}</p></section>')
        return "\n".join(out), "no Lindelöf comparison"
    head = str(comparison).splitlines()[0]
    out.append(f'<p class="verdict">Verdict: <code>{_esc(comparison.verdict)}</code> — {_esc(head)}</p>')
    if comparison.lindelof_obstruction is not None:  # no Lindelöf equations, no defect
        out.append("</section>")
        return "\n".join(out), comparison.verdict
    condition = (
        ""
        if comparison.condition_28 is None
        else f"Condition (28): {'holds' if comparison.condition_28 else 'fails'}; "
    )
    true = "Novoselov's equations" if comparison.nonlinear else "(15)"
    defect = f"the Lindelöf defect {true} − (22) {'vanishes.' if comparison.defect_vanishes else 'is:'}"
    out.append(f"<p>{condition}{defect[0].upper() + defect[1:] if not condition else defect}</p>")
    if not comparison.defect_vanishes:
        out += [
            _block(sp.Eq(sp.Symbol(f"Δ_{_name(q)}"), e, evaluate=False)) for q, e in comparison.defect.items()
        ]
    out.append("</section>")
    return "\n".join(out), comparison.verdict


def _equations_section(system: System) -> str:
    models, reasons = applicable_models(system)
    out = [
        '<section id="equations"><h2>Equations of motion</h2>',
        '<p class="note">Every equation reads “expression = 0”; dots are time derivatives; '
        "λ are the Chetaev multipliers, μ the vakonomic ones, c the constants of the "
        "vakonomic family.</p>",
    ]
    for model, form in models:
        try:
            eqs = system.equations(model, form)
        except ChaplyginError as exc:
            reasons[f"{model}/{form}"] = str(exc)
            continue
        out.append(f'<h3 id="eq-{model}-{form}">{_esc(eqs.title)}</h3>')
        out += [_block(e) for e in eqs.equations]
    if reasons:
        out.append("<p>Not shown:</p><ul>")
        out += [f"<li><code>{_esc(k)}</code>: {_esc(v)}</li>" for k, v in reasons.items()]
        out.append("</ul>")
    out.append("</section>")
    return "\n".join(out)


def _exact_constraints(trajectory: Any) -> bool:
    """The run's model is reduced: it integrates only the independent velocities, so its
    constraint residual is zero by construction (round-off), not a measurement."""
    model = registry.MODELS.get(trajectory.model)
    return model is not None and model.reduced


def _energy_note(system: System) -> tuple[str, str]:
    """The energy column's heading, and (HTML) what E = T − U is for ``system``: an invariant
    whose drift measures the integration error, or a quantity that changes with the motion."""
    measure = "max |E − E(0)| / max(1, |E(0)|), E = T − U"
    forced = [mathml(sp.Symbol(f"Q_{_name(q)}")) for q, f in system.forces.items() if f != 0]
    if forced:
        return "energy change", (
            f"Energy change: {measure}. The non-potential forces ({', '.join(forced)}) do work, so "
            "E is not an invariant here: it changes by their work, dE/dt = Σ_s Q_s q̇_s, and this "
            "column measures that change, not an integration error."
        )
    if system.is_affine or not system.is_scleronomic:
        why = (
            "the system depends on time explicitly"
            if not system.is_affine
            else "the constraints are not homogeneous of degree 1 in the velocities: their forces do work"
            if system.is_nonlinear
            else "the constraints are affine"
        )
        return "energy change", (
            f"Energy change: {measure}. E is not an invariant here ({why}): this column measures "
            "how it changes along the motion, not an integration error."
        )
    from chaplygin.numeric.simulate import monitor

    if monitor(system).column == "jacobi_integral":
        return "Jacobi integral drift", (
            "Jacobi integral drift: max |h − h(0)| / max(1, |h(0)|), h = T₂ − T₀ − U (T₂, T₁, T₀: the "
            "parts of T quadratic, linear and free in the velocities). T has velocity-linear or "
            "velocity-free parts (a moving frame) but nothing depends on time, the constraints are "
            "homogeneous and no non-potential force acts: h, not E = T − U, is the invariant here, "
            "so its drift measures the integration error."
        )
    return "energy drift", (
        f"Energy drift: {measure}; E is an invariant here (scleronomic homogeneous constraints, no "
        "non-potential forces), so the drift measures the integration error."
    )


def _simulation_rows(comparison: Comparison) -> str:
    rows = []
    for label, tr in comparison.trajectories.items():
        dist = comparison.distance(label)
        k = int(np.argmax(dist)) if len(dist) else 0
        dmax = f"{dist[k]:.6g}" if len(dist) else "–"
        at = f"{tr.t[k]:.4g}" if len(dist) else "–"
        if _exact_constraints(tr):
            residual = '<td class="note" colspan="2">0 by construction (reduced)</td>'
        else:
            residual = (
                f'<td class="num">{np.max(tr.constraint_residual, initial=0.0):.3g}</td>'
                f'<td class="num">{(tr.constraint_residual[-1] if len(tr.t) else float("nan")):.3g}</td>'
            )
        rows.append(
            f'<tr><td><code>{_esc(label)}</code></td><td class="num">{dmax}</td><td class="num">{at}</td>'
            f'<td class="num">{tr.energy_drift():.3g}</td>{residual}'
            f"<td>{_esc(tr.status)}{': ' + _esc(tr.message) if not tr.success else ''}</td></tr>"
        )
    return "\n".join(rows)


def _simulation_section(
    system: System, comparison: Comparison | None, note: str, stage: Callable[[str], None]
) -> str:
    out = ['<section id="simulation"><h2>The models from the same initial state</h2>']
    if comparison is None:
        out.append(f'<p class="note">{_esc(note)}</p></section>')
        stage("figures")
        return "\n".join(out)
    ref = comparison.trajectories[comparison.reference]
    what = f"the path of ({', '.join(comparison.path)})" if comparison.path else "all coordinates"
    out.append(
        f"<p>{len(comparison.trajectories)} model(s) from t = {ref.t[0]:g} to {ref.t[-1]:g}, "
        f"{len(ref.t)} samples; distance: {_esc(what)}, from <code>{_esc(comparison.reference)}</code>.</p>"
    )
    energy, energy_note = _energy_note(system)
    out.append(
        f"<table><tr><th>model</th><th>max distance</th><th>at t</th><th>{energy}</th>"
        "<th>max constraint residual</th><th>final residual</th><th>status</th></tr>"
    )
    out.append(_simulation_rows(comparison))
    out.append("</table>")
    out += [f'<p class="warning">{_esc(note)}</p>' for note in comparison.notes]
    exact = [label for label, tr in comparison.trajectories.items() if _exact_constraints(tr)]
    residual = (
        "Constraint residual: max_β |f_β| (the constraint functions; Σ_s A_βs q̇_s + A_β0 for linear ones)"
    )
    if exact:
        residual += (
            f"; identically zero by construction for the reduced model(s) {', '.join(exact)}: they "
            "integrate only the independent velocities and compute the others from the "
            "constraints, so it is not plotted"
        )
    out.append(f'<p class="note">{energy_note} {_esc(residual)}.</p>')
    stage("figures")
    from chaplygin.numeric.comparison import FIGURES

    for kind in FIGURES:
        if kind == "paths" and not comparison.path:
            continue
        fig = comparison.figure(kind)
        out.append(f'<div class="figure" id="figure-{kind}">{_svg(fig)}</div>')
    out.append("</section>")
    return "\n".join(out)


def _paper_section(table: PaperTable) -> str:
    out = [
        '<section id="paper"><h2>The paper\'s printed equations (49)-(62)</h2>',
        "<p>The seed paper's §4 equations as they stand in the OCR'd text, typed by hand with "
        "their errors, beside chaplygin's derivation. <b>agree</b>: the printed line is the "
        "derived one. <b>transcription error</b>: it becomes the derived one once the marks "
        "lost or misread in printing or transcription are restored (listed). <b>differs in "
        "substance</b>: no such restoration explains the difference. Printed symbols: "
        "\\psi = ψ, \\theta = θ, \\varphi = φ; forces of (44)-(46): moments M_ψ, M_θ, M_φ on "
        "the angles and (V₁, V₂) on the centre.</p>",
        f'<p class="verdict">{_esc(table.summary())}.</p>',
        '<table class="paper"><colgroup><col style="width:12%"><col style="width:36%">'
        '<col style="width:30%"><col style="width:22%"></colgroup>'
        "<tr><th>eq.</th><th>as printed (OCR text; typed as it stands; restored)</th>"
        "<th>derived by chaplygin</th><th>verdict and restorations</th></tr>",
    ]
    for line in table.lines:
        cls = _VERDICT_CLASS[line.verdict]
        restored = ""
        if line.verdict != VERDICTS[0] and line.restored is not None:
            restored = f'<p class="note">restored:</p>{_cell(line.restored)}'
        repairs = "".join(f"<li>{_esc(r)}</li>" for r in line.repairs)
        out.append(
            f'<tr id="paper-{line.number.strip("()")}"><td>{_esc(line.number)}<br>'
            f'<span class="note">{_esc(line.what)}</span></td>'
            f'<td class="ocr"><code>{_esc(line.ocr)}</code>{_cell(line.printed)}{restored}</td>'
            f"<td>{_cell(line.derived)}</td>"
            f'<td><span class="verdict {cls}">{_esc(line.verdict)}</span>'
            f"{'<ul>' + repairs + '</ul>' if repairs else ''}</td></tr>"
        )
    out.append("</table>")
    if table.sets:
        out.append(
            "<p>Each group of three, forces set to zero, given to <code>chaplygin.classify</code>:</p><ul>"
        )
        out += [
            f"<li>{_esc(label)} {_esc(reading)}: {_esc(verdict)}</li>"
            for label, reading, verdict in table.sets
        ]
        out.append("</ul>")
    out.append("</section>")
    return "\n".join(out)


def _stability_row(row: Any) -> str:
    """One model's row of the stability table (an :class:`chaplygin.apps._steady.Assessed`)."""
    from chaplygin.apps._steady import describe, eigenvalue

    s = row.stability
    cls = {True: "holds", False: "fails"}.get(s.stable, "")
    point = _esc(", ".join(f"{k} = {v + 0.0:.6g}" for k, v in s.point.items()))
    if row.found is not None:
        point += f'<br><span class="note">found by a Newton search, holding {_esc(", ".join(row.found.fixed))}</span>'
    values = "<br>".join(_esc(eigenvalue(z, s.tolerance)) for z in s.eigenvalues)
    zeros = "<br>".join(_esc(f"{s.zeros.count(r)} {r}") for r in dict.fromkeys(s.zeros)) or "none"
    verdict = f'<span class="verdict {cls}">{_esc(s.kind)}</span>{_esc(s.verdict.removeprefix(s.kind))}'
    return (
        f'<tr><td><code>{_esc(row.model)}</code><br><span class="note">{_esc(describe(row.model))}</span></td>'
        f'<td>{point}</td><td class="num">{values}</td><td>{zeros}</td><td>{verdict}</td></tr>'
    )


def _stability_section(found: Any) -> str:
    """The steady motion asked for (``chaplygin report --at``; :func:`chaplygin.apps._steady.study`):
    one row per model with its eigenvalues, named zero eigenvalues and verdict, and the root
    loci as a figure, their numbers one click away."""
    from chaplygin.apps._steady import eigenvalue, locus_figure, locus_rows

    out = ['<section id="stability"><h2>Steady motion and stability</h2>']
    at = ", ".join(f"{k} = {v:.10g}" for k, v in found.at.items())
    out.append(
        f"<p>The steady motion at <code>{_esc(at)}</code> (a velocity q&#8242; of a coordinate q that is "
        "not ignorable is 0 where not given), linearised exactly in each model's reduced variables "
        "(<code>chaplygin.stability</code>). Zero eigenvalues that come from the family of steady "
        "motions or from integrals are named, and do not make the motion unstable.</p>"
    )
    if found.rows:
        out.append(
            "<table><tr><th>model</th><th>point</th><th>eigenvalues</th><th>zero eigenvalues</th>"
            "<th>verdict</th></tr>"
        )
        out += [_stability_row(row) for row in found.rows]
        out.append("</table>")
    if found.locus:
        name = next(iter(found.locus.values())).parameter
        out.append(
            f"<p>Root locus: the eigenvalues against <code>{_esc(name)}</code>, real parts above, "
            "imaginary parts below, one column per model.</p>"
        )
        out.append(f'<div class="figure" id="figure-locus">{_svg(locus_figure(found.locus))}</div>')
        for model, lc in found.locus.items():
            rows = "".join(
                f'<tr><td class="num">{value:.6g}</td><td>{_esc(kind)}</td>'
                f'<td class="num">{_esc(", ".join(eigenvalue(z, 1e-9, 5) for z in roots))}</td></tr>'
                for value, kind, roots in locus_rows(lc)
            )
            out.append(
                f"<details><summary>the numbers: <code>{_esc(model)}</code></summary><table>"
                f"<tr><th>{_esc(name)}</th><th>verdict</th><th>eigenvalues</th></tr>{rows}</table></details>"
            )
    out.append("</section>")
    return "\n".join(out)


def _not_simulated(src: _Source) -> str:
    """Why the report of ``src`` has no simulation ("" where it has the numbers for one)."""
    missing = [p.name for p in src.system.parameters if p.name not in src.parameters]
    if not missing and src.initial:
        return ""
    what = "numbers for the parameters " + ", ".join(missing) if missing else "initial state"
    return f"Not simulated: no {what} were given."


def _compare(
    src: _Source, models: Sequence[str] | None, t_end: float, samples: int, backend: str, **options: Any
) -> Comparison:
    from chaplygin.numeric.comparison import compare

    chosen = list(models or default_models(src.system))
    return compare(
        src.system,
        chosen,
        float(t_end),
        src.initial,
        src.parameters,
        samples=samples,
        backend=backend,
        **options,
    )


def report_comparison(
    source: Any,
    *,
    models: Sequence[str] | None = None,
    t_end: float = 20.0,
    samples: int = 401,
    backend: str = "numpy",
    parameters: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    **options: Any,
) -> Comparison | None:
    """The simulations a report of ``source`` shows (the arguments of :func:`write_report`; more
    ``options`` of :func:`chaplygin.numeric.comparison.compare`, e.g. ``time_limit``), to pass as
    its ``comparison``; None where the numbers for them are missing.  The command line runs them
    first, so that it can tell whether every run reached ``t_end``."""
    src = _source(source, parameters, initial)
    return None if _not_simulated(src) else _compare(src, models, t_end, samples, backend, **options)


def render_report(
    source: Any,
    *,
    models: Sequence[str] | None = None,
    t_end: float = 20.0,
    samples: int = 401,
    backend: str = "numpy",
    parameters: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    comparison: Comparison | None = None,
    paper: bool | PaperTable | None = None,
    progress: Callable[[str], None] | None = None,
    generator: str = GENERATOR,
    stability: Any = None,
) -> str:
    """The report as one HTML string (see :func:`write_report` for the arguments)."""
    from chaplygin._version import __version__

    src = _source(source, parameters, initial)
    system = src.system
    stage = progress or (lambda _name: None)

    stage("system")
    parts = [_system_section(src)]
    stage("integrability")
    integ, integ_verdict = _integrability_section(system)
    parts.append(integ)
    models_html, model_verdict = _models_section(system)
    parts.append(models_html)
    stage("equations")
    parts.append(_equations_section(system))
    stage("simulation")
    note = ""
    if comparison is None:
        note = _not_simulated(src)
        if not note:
            comparison = _compare(src, models, t_end, samples, backend)
    parts.append(_simulation_section(system, comparison, note, stage))
    from chaplygin.apps.bodyview import body_section

    body = body_section(system, comparison)  # a rolling body drawn rolling; "" for others
    parts.append(body)
    if stability is not None:
        parts.append(_stability_section(stability))
    stage("paper")
    if paper is None:
        paper = is_paper_sphere(system)
    if paper is not False:
        parts.append(_paper_section(paper if isinstance(paper, PaperTable) else paper_table()))

    title = f"{src.name} — chaplygin report"
    summary = f"Constraints {integ_verdict}; models: {model_verdict}."
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f'<meta name="generator" content="{_esc(generator)}">',
            f'<meta name="chaplygin-version" content="{_esc(__version__)}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body>",
            f"<h1>{_esc(src.name)}</h1>",
            f'<p class="verdict">{_esc(summary)}</p>',
            '<nav><a href="#system">system</a> · <a href="#integrability">integrability</a> · '
            '<a href="#models">models</a> · <a href="#equations">equations</a> · '
            '<a href="#simulation">simulation</a>'
            + (' · <a href="#body">the body rolling</a>' if body else "")
            + (' · <a href="#stability">stability</a>' if stability is not None else "")
            + (' · <a href="#paper">the paper\'s equations</a>' if paper is not False else "")
            + "</nav>",
            *parts,
            f'<footer><p class="note">Written by chaplygin {_esc(__version__)}. Equation numbers '
            "refer to Liang Li-fu and Chen Wei-dong, <i>The complementary property of Lindelöf's "
            "work and Chaplygin's work</i>, Applied Mathematics and Mechanics 21(8), 2000.</p></footer>",
            "</body></html>",
            "",
        ]
    )


def write_report(
    source: Any,
    path: str | os.PathLike[str],
    **options: Any,
) -> Path:
    """Write the HTML report of a system to ``path`` (atomically) and return the path.

    Parameters
    ----------
    source : System or SystemFile
        A :class:`~chaplygin.System`, or a loaded system file (anything with ``system``,
        ``parameters``, ``initial``, ``name`` and ``source`` attributes, such as
        :class:`chaplygin.io.files.SystemFile`), whose parameters and initial state feed the
        simulation.
    path : path-like
        The HTML file.  It is written through a temporary file and renamed, so an interrupted
        run leaves an earlier file intact.  An existing file is replaced.
    models : sequence of str, optional
        Models to simulate and compare, the reference first (default: the true motion and
        Lindelöf's equations, see :func:`default_models`).
    t_end, samples, backend
        Simulation time span ``(0, t_end)``, number of samples and backend.
    parameters, initial : mapping, optional
        Override or supply the numbers of the source.  Without them no simulation is run.
    comparison : Comparison, optional
        A comparison already run (then no simulation is run here).
    paper : bool or PaperTable, optional
        Include the table of the paper's printed equations (default: when the system is the
        paper's sphere, :func:`is_paper_sphere`); a :func:`paper_table` already computed is
        used as it is.
    progress : callable, optional
        Called with the name of each stage (:data:`STAGES`) as it starts.
    stability : Study, optional
        A steady motion's stability in some models, and root loci
        (:func:`chaplygin.apps._steady.study`): the section "Steady motion and stability".
    """
    from chaplygin.numeric.simulate import _atomic_write

    text = render_report(source, **options)
    data = text.encode("utf-8")

    def write(fh: Any) -> None:
        for start in range(0, len(data), 1 << 16):
            fh.write(data[start : start + (1 << 16)])

    return _atomic_write(path, write, text=False)
