"""Comparing models on any system (issue 28, item 3): the vakonomic constants, the default pair,
and two names of one motion.

Ground truth: the accelerations of the true motion at the start and the vakonomic momenta
``∂L_v/∂q̇_dep = ∂T/∂q̇_dep + A_depᵀ μ`` are computed here with SymPy from the kinetic energy and
the implicit constraints alone (Lagrange–d'Alembert with multipliers), not by chaplygin's models.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from typer.testing import CliRunner

import chaplygin
from chaplygin import ChaplyginError, compare, examples
from chaplygin.apps.cli import app

T_ = dynamicsymbols._t
RACER = Path(__file__).resolve().parent.parent / "benchmarks" / "systems" / "roller_racer.toml"
runner = CliRunner()


def sleigh_chain() -> tuple[Any, dict[str, float], dict[str, float]]:
    entry = examples.get("sleigh-chain")
    return entry.constructor(), dict(entry.initial), dict(entry.parameters)


def roller_racer() -> tuple[Any, dict[str, float], dict[str, float]]:
    sf = chaplygin.load(RACER)
    return sf.system, dict(sf.initial), dict(sf.parameters)


def by_hand(system: Any, state: dict[str, float], params: dict[str, float]) -> dict[str, Any]:
    """At ``state`` (every coordinate and velocity): the true accelerations q̈ from
    ``d/dt ∂T/∂q̇ − ∂T/∂q = Aᵀ λ``, ``d/dt (A q̇) = 0``, and ``∂T/∂q̇_dep``, ``A_dep``."""
    q = list(system.coordinates)
    qd = [x.diff(T_) for x in q]
    qdd = [x.diff(T_, 2) for x in q]
    acc = sp.symbols(f"a0:{len(q)}")
    T = system.kinetic_energy
    phis = list(system.implicit_constraints)
    A = sp.Matrix([[sp.diff(f, v) for v in qd] for f in phis])
    lam = sp.symbols(f"l0:{len(phis)}")
    rows = [
        sp.diff(sp.diff(T, v), T_) - sp.diff(T, x) - sum(lam[b] * A[b, s] for b in range(len(phis)))
        for s, (x, v) in enumerate(zip(q, qd))
    ] + [sp.diff(f, T_) for f in phis]
    names = {x: x.func.__name__ for x in q}
    numbers = {system.parameter(k): v for k, v in params.items()}

    def at(e: sp.Expr) -> sp.Expr:
        e = e.subs(dict(zip(qdd, acc))).subs({v: state[names[x] + "'"] for x, v in zip(q, qd)})
        return e.subs({x: state[names[x]] for x in q}).subs(numbers)

    solved = sp.solve([at(r) for r in rows], [*acc, *lam], dict=True)[0]
    dep = [q.index(x) for x in system.dependent]
    return {
        "accelerations": np.array([float(solved[a]) for a in acc]),
        "p_dep": np.array([float(at(sp.diff(T, qd[i]))) for i in dep]),
        "A_dep": np.array(at(A[:, dep]).tolist(), dtype=float),
    }


def start_accelerations(tr: Any, h: float) -> np.ndarray:
    """q̈(0) from the first three samples (spacing h) of every velocity: second order in h."""
    return np.array(
        [(-3 * tr[f"{n}'"][0] + 4 * tr[f"{n}'"][1] - tr[f"{n}'"][2]) / (2 * h) for n in tr.coordinates]
    )


# ---------------------------------------------------------------- constants on non-Chaplygin systems
@pytest.mark.parametrize("case", [sleigh_chain, roller_racer], ids=["sleigh-chain", "roller-racer"])
def test_match_starts_the_vakonomic_motion_with_the_true_accelerations(case) -> None:
    """constants='match' (μ(0) = 0) on a system that is not a Chaplygin system: the vakonomic motion
    starts with the true accelerations (computed here by hand) and its momenta ∂L_v/∂q̇_dep equal
    the numbers the note gives; 'zero' gives momenta 0 and other accelerations. On a11bdc0 compare
    refused the constants (they went to the true motion too)."""
    system, initial, params = case()
    h = 1e-4
    runs = {
        c: compare(
            system, ["chetaev", "vakonomic"], 2 * h, initial, params, samples=3, backend="numpy", constants=c
        )
        for c in ("match", "zero")
    }
    reference = runs["match"].trajectories["chetaev"]
    state = {k: float(v[0]) for k, v in {**reference.coordinates, **reference.velocities}.items()}
    hand = by_hand(system, state, params)
    scale = max(1.0, float(np.max(np.abs(hand["accelerations"]))))
    for c, cmp in runs.items():
        vak = cmp.trajectories["vakonomic"]
        mu0 = np.array([vak.multipliers[m][0] for m in sorted(vak.multipliers)])
        momenta = hand["p_dep"] + hand["A_dep"].T @ mu0  # ∂L_v/∂q̇_dep at t = 0, by hand
        off = np.max(np.abs(start_accelerations(vak, h) - hand["accelerations"])) / scale
        if c == "match":
            assert off < 1e-6, off
            np.testing.assert_allclose(momenta, hand["p_dep"], atol=1e-12)
            stated = [
                float(x.split(" = ")[1]) for x in cmp.notes[0].split(" (")[0].split(": ")[1].split(", ")
            ]
            np.testing.assert_allclose(stated, hand["p_dep"], rtol=1e-5, atol=1e-9)
        else:
            assert off > 1e-2, off  # another motion from the same q, q̇
            np.testing.assert_allclose(momenta, 0.0, atol=1e-12)
    np.testing.assert_allclose(start_accelerations(reference, h), hand["accelerations"], atol=1e-6 * scale)


@pytest.mark.parametrize("case", [sleigh_chain, roller_racer], ids=["sleigh-chain", "roller-racer"])
def test_the_default_comparison_of_a_system_that_is_not_chaplygin(case) -> None:
    """The paper's pair by default: Voronets' equations (the true motion) and the vakonomic motion
    from the same state, not Voronets' against Chetaev's (the same motion, shown on a11bdc0
    without a word). Both conserve the energy T (homogeneous constraints, no forces), and they
    part: the vakonomic motion is another motion."""
    system, initial, params = case()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the roller racer's Voronets equations meet a pole
        cmp = compare(system, None, 5.0, initial, params, samples=51)
    assert list(cmp.trajectories) == ["voronets", "vakonomic"]
    assert cmp.notes[0].startswith("vakonomic: c_1 = ") and "'match'" in cmp.notes[0]
    assert "not conserved" in cmp.notes[0]
    assert not any("are the same motion" in note for note in cmp.notes)
    for tr in cmp.trajectories.values():
        assert tr.success and tr.energy_conserved and tr.energy_drift() < 1e-8
    assert np.max(cmp.distance("vakonomic")) > 0.1


def test_the_default_comparison_of_a_chaplygin_system() -> None:
    """Chaplygin's equations, the vakonomic motion from the same state, and Lindelöf's."""
    from chaplygin.numeric.comparison import default_models

    sphere = examples.rolling_sphere()
    assert default_models(sphere) == ["chaplygin", "vakonomic", "lindelof"]
    entry = examples.get("rolling-sphere")
    cmp = compare(sphere, None, 2.0, entry.initial, entry.parameters, samples=21)
    assert list(cmp.trajectories) == ["chaplygin", "vakonomic", "lindelof"]
    assert "conserved along the motion" in cmp.notes[0] and len(cmp.notes) == 1  # c ≠ 0: two motions


# ---------------------------------------------------------------- the constants go to the vakonomic models
def test_constants_go_to_the_vakonomic_models_only() -> None:
    """The true motion takes no constants and is not refused for them; the family and the
    multiplier form with the same constants are one motion (noted), another than Lindelöf's."""
    knife = examples.knife_edge()
    start, params = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 0.2}, {"m": 1.0, "J": 0.5}
    models = ["chaplygin", "vakonomic_family", "vakonomic", "lindelof"]
    cmp = compare(knife, models, 1.0, start, params, samples=11, constants={"c_1": 0.5})
    plain = compare(knife, ["chaplygin"], 1.0, start, params, samples=11)
    assert np.array_equal(cmp.trajectories["chaplygin"]["x"], plain.trajectories["chaplygin"]["x"])
    assert (
        np.max(np.abs(cmp.trajectories["vakonomic"]["x"] - cmp.trajectories["vakonomic_family"]["x"])) < 1e-7
    )
    assert np.max(np.abs(cmp.trajectories["vakonomic"]["x"] - cmp.trajectories["lindelof"]["x"])) > 1e-3
    assert cmp.notes == [
        "vakonomic_family, vakonomic: c_1 = 0.5 (given); c_β are the momenta ∂L_v/∂q̇ of the dependent "
        "coordinates y, conserved along the motion",
        "vakonomic_family and vakonomic are the same motion (the vakonomic motion with these constants): "
        "their distance in the table is integration error, not a difference of models",
    ]
    zero = compare(knife, ["vakonomic", "lindelof"], 1.0, start, params, samples=11, constants="zero")
    assert "vakonomic and lindelof are the same motion" in zero.notes[1]
    assert np.max(zero.distance("lindelof")) < 1e-7
    with pytest.raises(ChaplyginError, match="none of the models chaplygin, lindelof takes them"):
        compare(knife, ["chaplygin", "lindelof"], 1.0, start, params, constants="match")


def test_two_names_of_the_true_motion_are_said_to_be_one() -> None:
    system, initial, params = sleigh_chain()
    cmp = compare(system, ["voronets", "chetaev", "voronets/new"], 1.0, initial, params, samples=11)
    assert cmp.notes == [
        "voronets, chetaev and voronets/new are the same motion (the true motion): their distance in "
        "the table is integration error, not a difference of models"
    ]
    assert "integration error" in cmp.summary() and np.max(cmp.distance("chetaev")) < 1e-8


@pytest.mark.parametrize(
    ("constants", "says"),
    [
        ("zeros", r"constants = 'zeros': give c_β .*\{'c_1': …, 'c_2': …, 'c_3': …\}.*'match'.*'zero'"),
        (
            [1.0, 2.0],
            r"constants: 2 value\(s\) given for 3 constraint\(s\).*\{'c_1': …, 'c_2': …, 'c_3': …\}",
        ),
        ({"c_4": 1.0}, r"unknown key 'c_4'; the keys are 'c_1', 'c_2', 'c_3'.*constants='match' or 'zero'"),
        ([1.0, "a", 2.0], r"constants\[1\] = 'a' is not a number"),
    ],
)
def test_bad_constants_in_python_name_what_python_takes(constants: Any, says: str) -> None:
    system, initial, params = sleigh_chain()
    with pytest.raises(ChaplyginError, match=says):
        compare(system, ["voronets", "vakonomic"], 1.0, initial, params, constants=constants)


# ---------------------------------------------------------------- the command line
def test_compare_on_the_command_line_with_constants(tmp_path: Path, monkeypatch) -> None:
    """The issue's command runs (no --out: the table only), and --constants takes match, zero and
    numbers by name or in order; by name and in order give the same motion."""
    monkeypatch.chdir(tmp_path)
    args = ["compare", "example:sleigh-chain", "--models", "chetaev,vakonomic", "--t-end", "5"]
    result = runner.invoke(app, args)
    assert list(tmp_path.iterdir()) == []  # nothing written without --out
    assert result.exit_code == 0, result.output
    assert "chetaev " in result.stdout and "vakonomic " in result.stdout
    assert "note: vakonomic: c_1 = 0.194709" in result.stdout
    rows = {}
    for given in ("c_1=0.1,c_2=0,c_3=-0.2", "0.1,0,-0.2", "zero"):
        out = tmp_path / given.replace(",", "_")
        result = runner.invoke(
            app,
            ["compare", "example:sleigh-chain", "-t", "2", "-n", "11", "--constants", given, "-o", str(out)],
        )
        assert result.exit_code == 0, result.output
        rows[given] = (out / "vakonomic.csv").read_text()
        assert "voronets " in result.stdout and "chetaev" not in result.stdout  # the default pair
    assert rows["c_1=0.1,c_2=0,c_3=-0.2"] == rows["0.1,0,-0.2"] != rows["zero"]
    racer = runner.invoke(app, ["compare", str(RACER), "-t", "2", "-n", "11", "--constants", "match"])
    assert racer.exit_code == 0, racer.output
    assert "Roller racer" in racer.stdout and "vakonomic: c_1 = 0.197964, c_2 = 0.789211" in racer.stdout


@pytest.mark.parametrize(
    ("given", "says"),
    [
        ("c_4=1,c_2=0,c_3=0", "no constant c_4: Chain of 3 sleighs has 3 constraints"),
        ("1,2", "2 numbers given: Chain of 3 sleighs has 3 constraints"),
        ("c_1=1", "no value for c_2, c_3"),
        ("1,a,2", "'a' is not a finite number"),
        ("c_1=1,2,3", "give every constant by name or none"),
        ("matched", "'matched' is not a finite number"),
    ],
)
def test_bad_constants_on_the_command_line_name_what_it_takes(given: str, says: str) -> None:
    result = runner.invoke(app, ["compare", "example:sleigh-chain", "-t", "1", "--constants", given])
    assert result.exit_code == 2
    text = " ".join(result.output.replace("│", " ").split())
    assert says in text and "match" in text and "zero" in text and "c_1=" in text, text
    assert "constants=" not in text and "'match'" not in text  # the command line's syntax, not Python's


def test_the_fallback_at_a_pole_says_whether_its_rows_share_the_pole() -> None:
    """Review of issue 28: the sleigh on an incline with ``y' = tan θ x'`` was shown past θ = π/2 by
    the Chetaev model "with multipliers, no pole", yet its constraint row −sin θ/cos θ·ẋ + ẏ has
    that pole (energy drift 5e-6 against 1e-10 written implicitly): the note says so now."""
    systems = RACER.parent
    notes = {}
    for name in ("sleigh_incline_tan", "sleigh_incline_implicit"):
        loaded = chaplygin.load(systems / f"{name}.toml")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = compare(loaded.system, ["chaplygin"], 3.0, loaded.initial, loaded.parameters)
        notes[name] = " ".join(result.notes)
    assert "shown instead: the chetaev model" in notes["sleigh_incline_tan"]
    assert "its rows have that pole too" in notes["sleigh_incline_tan"]
    assert (
        "no pole" in notes["sleigh_incline_implicit"] and "pole too" not in notes["sleigh_incline_implicit"]
    )
