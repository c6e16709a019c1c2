"""Simulation of every model: known motions, invariants, agreement between forms, failures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sympy.physics.mechanics import dynamicsymbols

from chaplygin import ChaplyginError, System, compare, examples, simulate

t = dynamicsymbols._t
SPHERE_START = {
    "psi": 0.3,
    "theta": 1.0,
    "phi": 0.1,
    "x": 0.0,
    "y": 0.0,
    "psi'": 0.5,
    "theta'": 0.4,
    "phi'": -0.7,
}
UNIT = {"m": 1.0, "a": 1.0}


@pytest.fixture(scope="module")
def sphere():
    return examples.rolling_sphere()


@pytest.fixture(scope="module")
def sphere_runs(sphere):
    return {
        model: simulate(sphere, model, 100.0, SPHERE_START, UNIT, samples=501)
        for model in ("chetaev", "chaplygin", "lindelof")
    }


def omega(tr) -> np.ndarray:
    """Space components of ω (z-x-z Euler angles), computed from the trajectory."""
    psi, theta = tr["psi"], tr["theta"]
    dpsi, dtheta, dphi = tr["psi'"], tr["theta'"], tr["phi'"]
    return np.array(
        [
            dtheta * np.cos(psi) + dphi * np.sin(theta) * np.sin(psi),
            dtheta * np.sin(psi) - dphi * np.sin(theta) * np.cos(psi),
            dpsi + dphi * np.cos(theta),
        ]
    )


def test_sphere_true_motion_keeps_omega_and_centre_velocity(sphere_runs) -> None:
    for model in ("chetaev", "chaplygin"):
        tr = sphere_runs[model]
        assert tr.success, tr.message
        w = omega(tr)
        assert np.max(np.abs(w - w[:, :1])) < 1e-8
        for v in ("x'", "y'"):
            assert np.max(np.abs(tr[v] - tr[v][0])) < 1e-8
        assert tr.energy_drift() <= 1e-9
        assert np.max(tr.constraint_residual) <= 1e-9


def test_sphere_chetaev_and_chaplygin_agree(sphere_runs) -> None:
    a, b = sphere_runs["chetaev"], sphere_runs["chaplygin"]
    for name in a.coordinates:
        assert np.max(np.abs(a[name] - b[name])) < 1e-7 * max(1.0, np.max(np.abs(a[name])))
    assert set(a.multipliers) == {"lambda_1", "lambda_2"}
    assert np.max(np.abs(a["lambda_1"])) < 1e-8  # no friction force needed by a free sphere


def test_lindelof_run_differs_and_comparison_says_by_how_much(sphere) -> None:
    result = compare(sphere, ["chaplygin", "lindelof", "chetaev"], 30.0, SPHERE_START, UNIT, samples=301)
    far, near = result.distance("lindelof"), result.distance("chetaev")
    assert np.max(far) > 1.0 and np.max(near) < 1e-6
    text = result.summary()
    assert "lindelof" in text and "max distance of path (x, y)" in text
    assert result.trajectories["lindelof"].energy_drift() <= 1e-9


def test_comparison_figures(sphere, tmp_path) -> None:
    result = compare(sphere, ["chaplygin", "lindelof"], 5.0, SPHERE_START, UNIT, samples=51)
    paths = result.save_figures(tmp_path)
    assert [p.name for p in paths] == ["paths.svg", "coordinates.svg", "invariants.svg"]
    assert all(p.read_text().startswith("<?xml") for p in paths)
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("model", ["chetaev", "chaplygin"])
def test_rolling_disk_energy_over_t_100(model: str) -> None:
    disk = examples.rolling_disk()
    start = {
        "psi": 0.0,
        "theta": 0.2,
        "phi": 0.0,
        "x": 0.0,
        "y": 0.0,
        "psi'": 0.3,
        "theta'": 0.0,
        "phi'": 8.0,
    }
    params = {"m": 1.0, "r": 1.0, "A": 0.25, "C": 0.5, "g": 9.81}
    tr = simulate(disk, model, 100.0, start, params, samples=201)
    assert tr.success, tr.message
    assert tr.energy_drift() <= 1e-9
    assert np.max(tr.constraint_residual) <= 1e-9


def test_vertical_disk_closed_form() -> None:
    """φ = ω_φ t + φ0, θ = ω_θ t + θ0, x = ρ(sin φ − sin φ0) + x0, y = −ρ(cos φ − cos φ0) + y0."""
    disk = examples.vertical_rolling_disk()
    w_theta, w_phi, theta0, phi0, x0, y0, R = 2.0, 0.7, 0.1, 0.4, 1.0, -2.0, 0.5
    start = {"theta": theta0, "phi": phi0, "x": x0, "y": y0, "theta'": w_theta, "phi'": w_phi}
    for model in ("chetaev", "chaplygin", "lindelof"):
        tr = simulate(disk, model, 50.0, start, {"m": 1.0, "R": R, "I": 0.3, "J": 0.2}, samples=201)
        phi = w_phi * tr.t + phi0
        rho = R * w_theta / w_phi
        expected = {
            "theta": w_theta * tr.t + theta0,
            "phi": phi,
            "x": rho * (np.sin(phi) - np.sin(phi0)) + x0,
            "y": -rho * (np.cos(phi) - np.cos(phi0)) + y0,
        }
        for name, values in expected.items():
            assert np.max(np.abs(tr[name] - values)) < 1e-9 * max(1.0, np.max(np.abs(values))), (model, name)


def test_vakonomic_runs_from_the_same_state(sphere) -> None:
    family = simulate(
        sphere, "vakonomic_family", 10.0, SPHERE_START, UNIT, samples=101, constants=[0.2, -0.1]
    )
    multiplier = simulate(sphere, "vakonomic", 10.0, SPHERE_START, UNIT, samples=101, constants=[0.2, -0.1])
    for name in family.coordinates:
        assert np.max(np.abs(family[name] - multiplier[name])) < 1e-7
    assert set(multiplier.multipliers) == {"mu_1", "mu_2"}
    matched = simulate(sphere, "vakonomic", 1.0, SPHERE_START, UNIT, samples=11, constants="match")
    assert matched["mu_1"][0] == 0.0 and matched["mu_2"][0] == 0.0
    given = simulate(sphere, "vakonomic", 1.0, SPHERE_START, UNIT, samples=11, multipliers=[0.5, 0.25])
    assert given["mu_1"][0] == 0.5 and given["mu_2"][0] == 0.25


def test_initial_data_errors(sphere) -> None:
    with pytest.raises(ChaplyginError, match="missing theta'"):
        simulate(sphere, "chaplygin", 1.0, {k: v for k, v in SPHERE_START.items() if k != "theta'"}, UNIT)
    with pytest.raises(ChaplyginError, match=r"x' = 5 violates the constraints.*residual"):
        simulate(sphere, "chaplygin", 1.0, {**SPHERE_START, "x'": 5.0}, UNIT)
    with pytest.raises(ChaplyginError, match="no value for a"):
        simulate(sphere, "chaplygin", 1.0, SPHERE_START, {"m": 1.0})
    with pytest.raises(ChaplyginError, match="'z' is neither a coordinate"):
        simulate(sphere, "chaplygin", 1.0, {**SPHERE_START, "z": 1.0}, UNIT)
    with pytest.raises(ChaplyginError, match="unknown backend"):
        simulate(sphere, "chaplygin", 1.0, SPHERE_START, UNIT, backend="fortran")
    # a consistent dependent velocity is accepted, keyed by the dynamicsymbol
    psi, theta, phi, x, y = sphere.coordinates
    ok = {
        psi: 0.3,
        theta: np.pi / 2,
        phi: 0.0,
        x: 0.0,
        y: 0.0,
        psi.diff(t): 0.0,
        theta.diff(t): 0.0,
        phi.diff(t): 1.0,
        x.diff(t): -np.cos(0.3),
    }
    assert simulate(sphere, "chaplygin", 1.0, ok, UNIT, samples=3).success


def test_blow_up_returns_partial_trajectory() -> None:
    x, z = dynamicsymbols("x z")
    s = System([x, z], (x.diff(t) ** 2 + z.diff(t) ** 2) / 2, {z.diff(t): x.diff(t)}, force_function=x**4)
    tr = simulate(s, "chaplygin", 10.0, {"x": 1.0, "z": 0.0, "x'": 1.0}, samples=101)
    assert tr.status == "failed" and tr.message
    assert 0 < len(tr.t) < 101 and tr.t[-1] < 10.0
    assert np.all(np.isfinite(tr["x"]))


def test_export_csv_and_npz(sphere, tmp_path) -> None:
    tr = simulate(sphere, "chetaev", 1.0, SPHERE_START, UNIT, samples=11)
    csv = tr.to_csv(tmp_path / "run.csv")
    header = csv.read_text().splitlines()[0].split(",")
    assert header[:6] == ["t", "psi", "theta", "phi", "x", "y"]
    assert {"x'", "energy", "constraint_residual", "lambda_1"} <= set(header)
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert data.shape == (11, len(header))
    assert np.allclose(data[:, header.index("x'")], tr["x'"], rtol=1e-15)
    npz = np.load(tr.to_npz(tmp_path / "run.npz"))
    assert np.array_equal(npz["theta"], tr["theta"]) and "energy" in npz.files


def test_failed_write_keeps_previous_file(sphere, tmp_path) -> None:
    tr = simulate(sphere, "chaplygin", 1.0, SPHERE_START, UNIT, samples=5)
    target = tmp_path / "run.csv"
    target.write_text("previous")
    broken = type(tr)(**{**tr.__dict__, "energy": np.ones(2)})  # wrong length: writing fails
    with pytest.raises(ValueError):
        broken.to_csv(target)
    assert target.read_text() == "previous"
    assert [p.name for p in tmp_path.iterdir()] == ["run.csv"]


def test_matching_constants_for_the_family(sphere) -> None:
    """constants="match": μ(0) = 0 in the multiplier form equals c = ∂T/∂q̇_dep(0) in the family."""
    family = simulate(sphere, "vakonomic_family", 5.0, SPHERE_START, UNIT, samples=51, constants="match")
    multiplier = simulate(sphere, "vakonomic", 5.0, SPHERE_START, UNIT, samples=51, constants="match")
    for name in family.coordinates:
        assert np.max(np.abs(family[name] - multiplier[name])) < 1e-7


KNIFE_START = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 0.2}
KNIFE_P = {"m": 1.0, "J": 0.5}


@pytest.mark.parametrize(
    ("model", "options", "says"),
    [
        ("vakonomic", {"multipliers": "match"}, r"multipliers='match'.*give constants='match'"),
        ("vakonomic", {"multipliers": ["a"]}, r"multipliers\[0\] = 'a' is not a number"),
        ("vakonomic", {"multipliers": {"mu_1": "x"}}, r"multipliers: mu_1 = 'x' is not a number"),
        ("vakonomic", {"multipliers": {"nu": 0.1}}, r"multipliers: unknown key 'nu'; give μ\(0\) for mu_1"),
        ("vakonomic", {"multipliers": [1.0, 2.0]}, r"multipliers: 2 value\(s\) given for 1 constraint"),
        ("vakonomic", {"multipliers": [float("nan")]}, r"multipliers\[0\] = nan is not finite"),
        ("vakonomic", {"multipliers": [0.1], "constants": [0.2]}, r"give one of them"),
        ("vakonomic", {"constants": "foo"}, r"constants = 'foo': give c_β .*'match'"),
        ("vakonomic_family", {"constants": ["foo"]}, r"constants\[0\] = 'foo' is not a number"),
        (
            "vakonomic_family",
            {"constants": {"c_2": 1.0}},
            r"constants: unknown key 'c_2'; the keys are 'c_1'",
        ),
        ("vakonomic_family", {"multipliers": [0.5]}, r"takes the constants c_β .*not μ\(0\)"),
    ],
)
def test_vakonomic_options_that_are_not_numbers_are_refused_by_name(model, options, says) -> None:
    """multipliers/constants: a string, a wrong count, a non-finite value or an unknown key is an
    InputError naming the option and what it takes (on main: a bare ValueError for
    multipliers='match', μ(0) = 2.0 silently dropped, NaN integrated, the family ignoring μ(0))."""
    from chaplygin import InputError

    knife = examples.knife_edge()
    with pytest.raises(InputError, match=says):
        simulate(knife, model, 1.0, KNIFE_START, KNIFE_P, samples=3, backend="numpy", **options)


def test_vakonomic_options_that_are_numbers_give_mu0() -> None:
    """What is accepted: μ(0) as a number (g = 1), a sequence or a mapping by name; 'match' is μ(0) = 0."""
    knife = examples.knife_edge()
    for given in (0.5, [0.5], {"mu_1": 0.5}):
        run = simulate(knife, "vakonomic", 0.5, KNIFE_START, KNIFE_P, samples=3, multipliers=given)
        assert run.success and run["mu_1"][0] == 0.5
    matched = simulate(knife, "vakonomic", 0.5, KNIFE_START, KNIFE_P, samples=3, constants="match")
    zero = simulate(knife, "vakonomic", 0.5, KNIFE_START, KNIFE_P, samples=3, multipliers=[0.0])
    assert matched["mu_1"][0] == 0.0 and np.array_equal(matched.table(), zero.table())


def test_compare_falls_back_to_the_multiplier_model_at_a_pole():
    """A knife edge heading through φ = π/2, where ẏ = tan φ ẋ has a pole: compare warns and shows
    the Chetaev motion under the label 'chaplygin'; Lindelöf's run (no multiplier form) stops."""
    from chaplygin import ChaplyginWarning

    knife = examples.knife_edge()
    start = {"x": 0.0, "y": 0.0, "phi": 1.2, "x'": 1.0, "phi'": 1.0}
    with pytest.warns(ChaplyginWarning, match="pole") as caught:
        cmp = compare(knife, ["chaplygin", "lindelof"], 1.0, start, {"m": 1.0, "J": 0.5}, samples=21)
    assert len(caught) == 2 and len(cmp.notes) == 2
    true = cmp.trajectories["chaplygin"]
    assert true.model == "chetaev" and true.success and true.energy_drift() < 1e-8
    assert "chetaev" in cmp.notes[0] and "between t = 0.35 and 0.4" in cmp.notes[0]
    lind = cmp.trajectories["lindelof"]
    assert lind.failure == "pole" and lind.t[-1] < np.pi / 2 - 1.2 and "lindelof" in cmp.notes[1]
    assert "note: chaplygin" in cmp.summary()


def test_compare_without_a_pole_has_no_notes(recwarn):
    knife = examples.knife_edge()
    start = {"x": 0.0, "y": 0.0, "phi": 0.2, "x'": 1.0, "phi'": 0.5}
    cmp = compare(knife, ["chaplygin", "lindelof"], 1.0, start, {"m": 1.0, "J": 0.5}, samples=21)
    assert cmp.notes == [] and all(tr.success for tr in cmp.trajectories.values())
    assert cmp.trajectories["chaplygin"].model == "chaplygin" and not recwarn.list


def ball_in_a_rotating_frame() -> System:
    """A homogeneous ball on a turntable spinning at Ω, written in the table's frame: the centre
    (X, Y) and z-x-z Euler angles relative to the table.  The constraints (rolling on the table,
    at rest in this frame) are homogeneous and nothing depends on t, but T has velocity-linear
    and velocity-free parts: T = ½ m |(Ẋ − Ω Y, Ẏ + Ω X)|² + ⅕ m a² |ω_rel + Ω e_z|²."""
    import sympy as sp

    psi, theta, phi, x, y = dynamicsymbols("psi theta phi X Y")
    m, a, rate = sp.symbols("m a Omega", positive=True)
    d = [c.diff(t) for c in (psi, theta, phi, x, y)]
    w = sp.Matrix(
        [
            d[1] * sp.cos(psi) + d[2] * sp.sin(theta) * sp.sin(psi),
            d[1] * sp.sin(psi) - d[2] * sp.sin(theta) * sp.cos(psi),
            d[0] + d[2] * sp.cos(theta),
        ]
    )
    inertial = w + sp.Matrix([0, 0, rate])
    v = sp.Matrix([d[3] - rate * y, d[4] + rate * x])
    T = m / 2 * v.dot(v) + sp.Rational(1, 5) * m * a**2 * inertial.dot(inertial)
    return System([psi, theta, phi, x, y], T, {d[3]: a * w[1], d[4]: -a * w[0]}, name="ball, table frame")


def jacobi_integral(tr, m: float, a: float, rate: float) -> np.ndarray:
    """h = T₂ − T₀ (V = 0), from the samples, with the formulas of the docstring above."""
    q = {c: tr[c] for c in ("psi", "theta", "phi", "X", "Y")}
    qd = {c: tr[c + "'"] for c in q}
    wx = qd["theta"] * np.cos(q["psi"]) + qd["phi"] * np.sin(q["theta"]) * np.sin(q["psi"])
    wy = qd["theta"] * np.sin(q["psi"]) - qd["phi"] * np.sin(q["theta"]) * np.cos(q["psi"])
    wz = qd["psi"] + qd["phi"] * np.cos(q["theta"])
    t2 = m / 2 * (qd["X"] ** 2 + qd["Y"] ** 2) + m * a**2 / 5 * (wx**2 + wy**2 + wz**2)
    t0 = m / 2 * rate**2 * (q["X"] ** 2 + q["Y"] ** 2) + m * a**2 / 5 * rate**2
    return t2 - t0


def test_a_rotating_frame_monitors_jacobis_integral(tmp_path) -> None:
    """Time-independent but with T₁, T₀ parts: E = T − U drifts by physics (4.8 relative on main, where
    it was shown as 'energy drift'); the conserved quantity is Jacobi's h = T₂ − T₀ + V, which the
    column holds and is named after, for every model (the vakonomic one too: μ·φ drops out of h)."""
    ball = ball_in_a_rotating_frame()
    params = {"m": 1.3, "a": 0.1, "Omega": 2.0}
    start = {
        "psi": 0.3,
        "theta": 1.0,
        "phi": 0.1,
        "X": 0.5,
        "Y": 0.0,
        "psi'": 0.5,
        "theta'": 0.4,
        "phi'": -0.7,
    }
    for model, t_end, options in (
        ("voronets", 10.0, {}),
        ("chetaev", 10.0, {}),
        ("vakonomic", 2.0, {"multipliers": [0.1, -0.2]}),
    ):
        tr = simulate(ball, model, t_end, start, params, samples=201, **options)
        assert tr.success, tr.message
        h = jacobi_integral(tr, 1.3, 0.1, 2.0)
        assert "jacobi_integral" in tr.columns and "energy" not in tr.columns
        assert tr.energy_label == "Jacobi integral drift"
        assert np.max(np.abs(tr["jacobi_integral"] - h)) < 1e-12 * max(1.0, np.max(np.abs(h)))
        assert np.ptp(h) < 1e-7 and tr.energy_drift() < 1e-7  # conserved: the drift is numerical
        with pytest.raises(KeyError, match="Jacobi's integral"):
            tr["energy"]
    header = tr.to_csv(tmp_path / "run.csv").read_text().splitlines()[0].split(",")
    assert "jacobi_integral" in header and "energy" not in header
    both = compare(ball, ["voronets", "chetaev"], 2.0, start, params, samples=21)
    assert "Jacobi integral drift" in both.summary() and "energy" not in both.summary()
    # the same table in the inertial frame has affine constraints: E = T − U, and it is no invariant
    plain = {("x" if k == "X" else "y" if k == "Y" else k): v for k, v in start.items()}
    inertial = simulate(examples.turntable_ball(), "voronets", 1.0, plain, params, samples=11)
    assert "energy" in inertial.columns and inertial.energy_label == "energy change"


@pytest.mark.parametrize("backend", ["numpy", "c"])
@pytest.mark.parametrize(("t_end", "samples"), [(314.159, 2), (1000.0, 2), (1.0e4, 11)])
def test_a_pole_between_two_samples_stops_the_run(backend: str, t_end: float, samples: int) -> None:
    """The knife edge ẏ = tan φ ẋ with φ = 0.3 + t: φ crosses π/2 at t = π/2 − 0.3 ≈ 1.2708 and back
    over a pole every π, all between the two samples of a long run. On d1d83f5 the t = 314.159 run
    said 'success' 2.4e-6 off the true motion, and the longer ones failed by a step-size underflow
    (numpy) or succeeded (c), none naming the pole."""
    knife = examples.knife_edge()
    start = {"x": 0.0, "y": 0.0, "phi": 0.3, "x'": 1.0, "phi'": 1.0}
    tr = simulate(knife, "chaplygin", t_end, start, {"m": 1.0, "J": 0.5}, samples=samples, backend=backend)
    assert tr.status == "failed" and tr.failure == "pole", tr.message
    between = [float(x) for x in tr.message.split("between t = ")[1].split(":")[0].split(" and ")]
    pole = np.pi / 2 - 0.3
    assert between[0] < pole < between[1] and between[1] - between[0] < 1.0, tr.message  # (not over 2 poles)
    assert tr.t[-1] < pole


def test_a_second_run_does_no_symbolic_work(monkeypatch) -> None:
    """Issue 31: every simulate() substituted numbers into SymPy matrices (the initial state, the
    mass-matrix check: 1.6–2.1 ms a call on the snakeboard); their functions are made once per
    system now, so a second run of each model, with other numbers, never reaches SymPy's
    substitution or evalf, and gives what a fresh system gives."""
    import sympy as sp

    from chaplygin import load

    path = Path(__file__).resolve().parent.parent / "benchmarks" / "systems" / "snakeboard_spring.toml"
    loaded = load(path)
    other = {**loaded.initial, "phi": 0.1, "psi'": -0.5}
    models = ("chetaev", "chaplygin", "voronets", "vakonomic", "lindelof", "vakonomic_family")
    for model in models:  # the first run of each model makes the functions
        simulate(loaded.system, model, 0.01, loaded.initial, loaded.parameters, samples=3)
    fresh = load(path).system  # an equal system that has made nothing yet
    expected = {m: simulate(fresh, m, 1.0, other, loaded.parameters, samples=11) for m in models}

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("symbolic work in a warm simulate()")

    for cls, name in [(c, n) for c in (sp.Basic, sp.MatrixBase) for n in ("xreplace", "subs")] + [
        (sp.core.evalf.EvalfMixin, "evalf"),
        (sp.MatrixBase, "evalf"),
    ]:
        monkeypatch.setattr(cls, name, refuse)
    for model in models:
        tr = simulate(loaded.system, model, 1.0, other, loaded.parameters, samples=11)
        assert tr.success, tr.message
        for name in tr.columns:
            np.testing.assert_array_equal(tr[name], expected[model][name], err_msg=f"{model}: {name}")


def test_equal_systems_start_equally_to_the_last_digit() -> None:
    """Issue 31: the start's matrices are evaluated by SymEngine functions made once per system,
    their internal symbols renamed by position first: SymEngine orders a sum's terms by hash, and
    the internal symbols of each system are numbered anew, so equal systems added the same terms
    in other orders (10 of 12 fresh sleigh chains gave other last digits of q̇_dep, c or μ(0), and
    `compare --constants` by name and in order other CSVs)."""
    from chaplygin.numeric.simulate import _matching_constants, _multipliers_from_constants, initial_state

    starts = set()
    for _ in range(6):
        chain = examples.sleigh_chain(3)
        params = {p.name: 0.7 + 0.1 * k for k, p in enumerate(chain.parameters)}
        names = [c.func.__name__ for c in chain.coordinates]
        initial = {name: x for name, x in zip(names, np.random.default_rng(1).uniform(-1, 1, chain.n))}
        initial |= {names[i] + "'": 0.3 - 0.2 * i for i in chain._ind}
        q, qd = initial_state(chain, initial, params, 0.0)
        c = _matching_constants(chain, q, qd, params, 0.0)
        mu = _multipliers_from_constants(chain, np.linspace(0.1, -0.2, chain.g), q, qd, params, 0.0)
        starts.add((*qd, *c, *mu))
    assert len(starts) == 1


def test_absolute_values_of_time_and_coordinates_in_the_constraints_derive_and_run(tmp_path) -> None:
    """ẏ = ẋ / (1 + |t − 1|) and ẏ = ẋ / (1 + |x|) (a file, as a user writes it): d|u|/du is
    sign(u) in the equations, not re(u)·d re(u)/du + im(u)·d im(u)/du (which no printer writes: on
    5d469ee `chaplygin simulate` stopped with "unexpected PrintMethodNotImplementedError … im"),
    and Chaplygin's reduced run is the multiplier model's motion, which differentiates nothing."""
    import chaplygin
    from chaplygin.models.derive import derive

    for slip in ("x'/(1 + abs(t - 1))", "x'/(1 + abs(x))"):
        path = tmp_path / "blade.toml"
        path.write_text(
            'name = "blade"\ncoordinates = ["x", "y", "phi"]\n[parameters]\nm = 1.0\n'
            "[energy]\nT = \"m/2*(x'^2 + y'^2 + phi'^2)\"\n"
            f'[constraints]\n"y\'" = "{slip}"\n'
            '[initial]\nx = -0.5\nphi = 0.0\n"x\'" = 1.0\n"phi\'" = 1.0\n',
            encoding="utf-8",
        )
        f = chaplygin.load(path)
        printed = str(derive(f.system, "chaplygin").equations)
        assert "sign(" in printed and "re(" not in printed and "im(" not in printed, printed
        runs = {model: chaplygin.simulate(f, model, 2.0, samples=5) for model in ("chaplygin", "chetaev")}
        assert runs["chaplygin"].success and runs["chetaev"].success
        for name in ("x", "y", "x'", "y'"):
            assert np.max(np.abs(runs["chaplygin"][name] - runs["chetaev"][name])) < 1e-7, (slip, name)


def _blade(tmp_path, name: str, body: str):
    """A system file of coordinates x, y, phi with ``body`` (its [energy]/[constraints]/… tables)."""
    import chaplygin

    path = tmp_path / f"{name}.toml"
    path.write_text(f'name = "{name}"\ncoordinates = ["x", "y", "phi", "z"]\n' + body, encoding="utf-8")
    return chaplygin.load(path)


def test_abs_in_the_constraints_linearises_as_its_smooth_branch(tmp_path) -> None:
    """The stability of ẏ = |x| tan φ ẋ at x = 1 (away from the kink) is that of ẏ = x tan φ ẋ,
    which has no abs(): the same eigenvalues (on 58663b9 the linearisation differentiated with
    plain SymPy and stopped with "unexpected PrintMethodNotImplementedError … im")."""
    import chaplygin

    common = "[parameters]\nm = 1.0\n[energy]\nT = \"m/2*(x'^2 + y'^2 + phi'^2 + z'^2)\"\nV = \"(x - 1)^2 + z^2\"\n"
    point = {"x": 1.0, "phi": 0.2, "z": 0.0, "x'": 0.0, "phi'": 0.0, "z'": 0.0}
    for model in ("chetaev", "chaplygin"):
        values = []
        for slip in ("abs(x)", "x"):
            f = _blade(tmp_path, "blade", common + f'[constraints]\n"y\'" = "{slip}*tan(phi)*x\'"\n')
            result = chaplygin.stability(f.system, point, f.parameters, model=model)
            values.append(np.sort_complex(np.asarray(result.eigenvalues)))
        np.testing.assert_allclose(values[0], values[1], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "tables",
    [
        '[constraints]\n"y\'" = "sign(x)*phi\'"\n',  # a coefficient that jumps at x = 0
        '[constraints]\n"y\'" = "tan(phi)*x\'"\n[holonomic]\nz = "z - abs(x)"\n',  # a kink at x = 0
    ],
)
def test_a_jump_that_needs_an_impulse_is_refused_with_a_reason(tmp_path, tables) -> None:
    """sign() in a constraint's coefficient, abs() in a holonomic relation: the equations hold
    DiracDelta (an impulse where the argument is zero), which no integrator takes; simulate
    says so (on 58663b9: "unexpected PrintMethodNotImplementedError … DiracDelta", SymPy's own
    error from the Python API)."""
    import chaplygin
    from chaplygin.errors import ModelError

    f = _blade(tmp_path, "jump", "[energy]\nT = \"(x'^2 + y'^2 + phi'^2 + z'^2)/2\"\n" + tables)
    with pytest.raises(
        ModelError, match=r"contain DiracDelta\(x\), the derivative of sign\(x\).*side of x = 0"
    ):
        chaplygin.simulate(f, "chetaev", 1.0, {"x": -0.5, "x'": 1.0}, samples=3, backend="numpy")


def test_a_fixed_step_run_across_a_kink_says_so(tmp_path) -> None:
    """ẏ = |x| ẋ + |sin φ| φ̇ from x = −0.5: x crosses 0 (a kink of the equations) between two
    samples, which the note of a gauss4 run names and brackets (the crossing time taken from a
    DOP853 run); on 2baf532 the run said nothing and was off by 1e-3 whatever its step (outside
    review). A run that stays on one side, and DOP853's, carry no such note."""
    import chaplygin

    f = _blade(
        tmp_path,
        "kink",
        "[parameters]\nm = 1.0\n[energy]\nT = \"m/2*(x'^2 + y'^2) + 1/2*phi'^2 + 1/2*z'^2\"\n"
        '[constraints]\n"y\'" = "abs(x)*x\' + abs(sin(phi))*phi\'"\n',
    )
    start = {"x": -0.5, "phi": 0.1, "x'": 1.0, "phi'": 1.0}
    fixed = chaplygin.simulate(f, "chaplygin", 2.0, start, samples=21, method="gauss4", step=0.01)
    [note] = [n for n in fixed.notes if "changes sign" in n]
    assert note.startswith("x changes sign between t = 0.4 and 0.5: the equations have a kink"), note
    assert "not to be trusted (a smaller step does not cure it): run DOP853" in note
    adaptive = chaplygin.simulate(f, "chaplygin", 2.0, start, samples=2001)
    crossing = adaptive.t[np.argmax(adaptive["x"] > 0)]
    assert 0.4 < crossing <= 0.5 and not any("changes sign" in n for n in adaptive.notes)
    right = chaplygin.simulate(
        f, "chaplygin", 2.0, {**start, "x": 0.5}, samples=21, method="gauss4", step=0.01
    )
    assert right.success and not any("changes sign" in n for n in right.notes)


def test_coulomb_friction_linearises_off_its_jump_and_not_on_it(tmp_path) -> None:
    """A blade driven along x by mu − mu sign(x') − c x'^3 + c (steady at x' = 1, where sign is 1):
    the Jacobian off the jump drops sign's derivative, and the eigenvalue of x' is the hand value
    −3c cos²φ (ẍ (1 + tan²φ) = Q_x with y' = tan φ x'); at x' = 0, on the jump, the Jacobian does
    not exist and stability says so (review of 2baf532: a mutant 5 off the jump still passed; on
    the jump, a "pole of the mass matrix" was reported)."""
    import chaplygin

    mu, c, phi = 0.5, 0.3, 0.2
    f = _blade(
        tmp_path,
        "drive",
        f"[parameters]\nmu = {mu}\nc = {c}\nk = 1.0\n[energy]\nT = \"(x'^2 + y'^2 + phi'^2 + z'^2)/2\"\n"
        'V = "k*z^2/2"\n[forces]\nx = "mu - mu*sign(x\') - c*x\'^3 + c"\n'
        '[constraints]\n"y\'" = "tan(phi)*x\'"\n',
    )
    point = {"x": 0.0, "phi": phi, "z": 0.0, "x'": 1.0, "phi'": 0.0, "z'": 0.0}
    result = chaplygin.stability(f.system, point, f.parameters, model="chetaev")
    real = np.sort(np.real(result.eigenvalues))
    assert abs(real[0] - (-3 * c * np.cos(phi) ** 2)) < 1e-9, result.eigenvalues
    with pytest.raises(
        ChaplyginError, match="the Jacobian of the chetaev equations of drive does not exist there"
    ):
        chaplygin.stability(f.system, {**point, "x'": 0.0}, f.parameters, model="chetaev")
