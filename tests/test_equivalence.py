"""The equivalence checker on hand-written equations (the way users check derivations)."""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ChaplyginError, equivalent, examples

t = dynamicsymbols._t
psi, theta, phi, x, y = dynamicsymbols("psi theta phi x y")
d = lambda q: q.diff(t)  # noqa: E731


@pytest.fixture(scope="module")
def sphere():
    return examples.rolling_sphere()


def lagrange(L: sp.Expr, q: sp.Expr) -> sp.Expr:
    return sp.diff(sp.diff(L, d(q)), t) - sp.diff(L, q)


def test_lindelofs_error_is_caught(sphere) -> None:
    """Constraints substituted into T before Lagrange's equations: not the true motion."""
    wrong = [lagrange(sphere.reduced_kinetic_energy, q) for q in sphere.independent]
    report = equivalent(sphere, wrong, sphere.equations("chetaev"))
    assert not report
    assert report.max_residual > 1e-2 and report.worst["acceleration"]
    assert "NOT equivalent" in str(report)


def test_hand_written_multiplier_equations(sphere) -> None:
    """The paper's (6a)-(6b) typed by hand, with λ(t): the same dynamics as Chaplygin's (15)."""
    lam1, lam2 = dynamicsymbols("lambda1 lambda2")
    T = sphere.kinetic_energy
    B = sphere.B
    eqs = [lagrange(T, q) + lam1 * B[0, k] + lam2 * B[1, k] for k, q in enumerate(sphere.independent)]
    eqs += [sp.Eq(sp.diff(sp.diff(T, d(x)), t), lam1), sp.Eq(sp.diff(sp.diff(T, d(y)), t), lam2)]
    assert equivalent(sphere, eqs, sphere.equations("chaplygin"))


def test_known_accelerations_of_the_free_sphere(sphere) -> None:
    """Constant ω in z-x-z Euler angles (free rigid body with spherical inertia)."""
    known = {
        psi.diff(t, 2): d(theta) * (d(phi) - d(psi) * sp.cos(theta)) / sp.sin(theta),
        theta.diff(t, 2): -d(phi) * d(psi) * sp.sin(theta),
        phi.diff(t, 2): d(theta) * (d(psi) - d(phi) * sp.cos(theta)) / sp.sin(theta),
    }
    assert equivalent(sphere, known, sphere.equations("chetaev"))
    known[theta.diff(t, 2)] *= 1.001
    report = equivalent(sphere, known, sphere.equations("chetaev"))
    assert not report and 1e-4 < report.max_residual < 1e-2


def test_parameters_can_be_fixed(sphere) -> None:
    report = equivalent(
        sphere, sphere.equations("chaplygin"), sphere.equations("chetaev"), parameters={"a": 2.0, "m": 3.0}
    )
    assert report.method == "numeric" and report


def test_bad_inputs(sphere) -> None:
    with pytest.raises(ChaplyginError, match="not linear"):
        equivalent(
            sphere, [psi.diff(t, 2) ** 2, theta.diff(t, 2), phi.diff(t, 2)], sphere.equations("chetaev")
        )
    with pytest.raises(ChaplyginError, match="unknown symbol"):
        equivalent(
            sphere,
            [psi.diff(t, 2) - sp.Symbol("g"), theta.diff(t, 2), phi.diff(t, 2)],
            sphere.equations("chetaev"),
        )
    with pytest.raises(ChaplyginError, match="do not determine"):
        equivalent(sphere, [psi.diff(t, 2)], sphere.equations("chetaev"))
    with pytest.raises(ChaplyginError, match="another system"):
        equivalent(sphere, examples.rolling_sphere().equations("chetaev"), sphere.equations("chetaev"))
    with pytest.raises(ChaplyginError, match="expected an Equations object"):
        equivalent(sphere, "psi'' = 0", sphere.equations("chetaev"))


# ---------------------------------------------------------------- where the states are drawn
# A derivation right on part of the configuration space only: (0.3, 1.3), where main sampled every
# coordinate, has cos φ > 0 and x > 0, so |cos φ| and |x| passed for cos φ and x there.
m_, J_, k_ = sp.symbols("m J k", positive=True)
KNIFE_T = m_ / 2 * (d(x) ** 2 + d(y) ** 2) + J_ / 2 * d(phi) ** 2


def _knife(b: sp.Expr, name: str, force_function: sp.Expr | None = None):
    from chaplygin import System

    return System([x, y, phi], KNIFE_T, {d(y): b * d(x)}, force_function=force_function, name=name)


def test_abs_cos_is_not_cos() -> None:
    """Equations derived from ẏ = |cos φ| ẋ are not those of ẏ = cos φ ẋ: their ÿ (and λ) have the
    wrong sign wherever cos φ < 0, so they contradict the constraint there."""
    true, wrong = _knife(sp.cos(phi), "cos"), _knife(sp.Abs(sp.cos(phi)), "|cos|")
    report = equivalent(true, wrong.equations("chetaev").accelerations, true.equations("chetaev"))
    assert not report and report.max_residual > 1e-2
    assert report.checked["phi"] == "(-π, π)" and report.checked["x"] == "±[0.1, 10]"
    assert "sampled" in str(report) and "phi ∈ (-π, π)" in str(report)
    assert report.samples == 24
    cos_at_worst = sp.cos(report.worst["state"]["phi"])
    assert cos_at_worst < 0  # where the two differ


def test_classify_catches_a_derivation_wrong_only_where_cos_is_negative() -> None:
    """ẍ with |cos φ| for one cos φ: right for cos φ > 0, wrong elsewhere; 'chetaev' on main."""
    from chaplygin import classify

    knife = _knife(sp.cos(phi), "cos")
    true = {d(d(x)): sp.sin(phi) * sp.cos(phi) * d(phi) * d(x) / (1 + sp.cos(phi) ** 2), d(d(phi)): 0}
    assert equivalent(knife, true, knife.equations("chetaev"))  # the hand derivation is right
    wrong = {
        **true,
        d(d(x)): true[d(d(x))].subs(sp.cos(phi) * sp.sin(phi), sp.Abs(sp.cos(phi)) * sp.sin(phi)),
    }
    assert wrong != true
    result = classify(knife, wrong)
    assert result.verdict == "none" and result.residuals["chetaev"] > 1e-2
    assert result.samples == 16 and result.checked["phi"] == "(-π, π)"
    assert "sampled" in str(result)


def test_lengths_are_sampled_with_both_signs() -> None:
    """U = −k x²/2: a derivation with |x| for x in ẍ is wrong only for x < 0."""
    knife = _knife(sp.cos(phi), "cos", force_function=-k_ * x**2 / 2)
    acc = knife.equations("chaplygin").accelerations
    assert acc[d(d(x))].has(x)
    v = sp.Dummy("v")  # keep ẋ: only the coordinate x becomes |x|
    wrong = {**acc, d(d(x)): acc[d(d(x))].xreplace({d(x): v}).xreplace({x: sp.Abs(x)}).xreplace({v: d(x)})}
    report = equivalent(knife, wrong, knife.equations("chetaev"))
    assert not report and report.worst["state"]["x"] < 0
