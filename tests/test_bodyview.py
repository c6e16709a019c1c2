"""The body drawn rolling (issue 18, item 6): the views follow the motion, the fragment is
self-contained, and in headless Chromium the report shows the body and the two models part."""

from __future__ import annotations

import html
import itertools
import json
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

import chaplygin
from chaplygin import InputError, compare, examples, simulate
from chaplygin.apps.bodyview import body_views, scenes, show_rolling, surface
from chaplygin.apps.report import write_report
from chaplygin.bodies import Ellipsoid, Sphere, Torus, initial_state, motion, rolling_body
from test_report import chromium, run_chromium

COIN = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 1.0, "theta'": 0.0, "phi'": 3.0}


@pytest.fixture(scope="module")
def coin():
    """Lindelöf's problem: a rounded coin (torus hull), both models from one leaning, turning state."""
    body = rolling_body(Torus(1.0, 0.25), mass=1.0, inertia=[0.3, 0.3, 0.55], g=9.81)
    return body, compare(body, ["chaplygin", "lindelof"], 3.0, COIN, {}, samples=61)


def rattleback():
    """Kane & Levinson's rattleback (docs/gallery/rattleback.md), spun the sense that reverses."""
    D = 2e-5
    body = rolling_body(
        Ellipsoid(0.2, 0.03, 0.02),
        mass=1.0,
        center_of_mass=(0, 0, -0.01),
        g=9.81,
        inertia=[[2e-4, D, 0], [D, 1.6e-3, 0], [0, 0, 1.7e-3]],
    )
    c, s = np.cos(0.01), np.sin(0.01)
    tilt = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return body, initial_state(body, R=tilt, omega=[0, 0, 5.0])


def test_a_rolling_ball_is_drawn_where_routh_puts_it() -> None:
    # a homogeneous ball keeps its angular velocity in space (Routh 1905): with ω = (0, 2, 0) it
    # rolls along +x at speed 2 and turns by the angle 2t about y
    ball = rolling_body(Sphere(1), mass=1, inertia=[0.4, 0.4, 0.4], g=9.81)
    run = simulate(
        ball, "chaplygin", 1.0, initial_state(ball, R=np.eye(3), omega=[0.0, 2.0, 0.0]), samples=11
    )
    mesh, times, rows = scenes(ball, run, snapshots=4)
    assert [len(row) for row in rows] == [1, 1, 1, 1] and times[0] == 0.0 and times[-1] == 1.0
    first = rows[0][0]
    arm0 = first.marker - first.centre
    assert np.linalg.norm(arm0) > 0.3  # the gold octant is off the centre: its turning shows
    for (scene,) in rows:
        t = scene.t
        assert np.allclose(scene.path[-1], [2 * t, 0, 0], atol=1e-6)  # the contact point so far
        assert np.allclose(scene.centre, [2 * t, 0, 1], atol=1e-6)
        c, s = np.cos(2 * t), np.sin(2 * t)
        assert np.allclose(
            scene.marker - scene.centre, np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ arm0, atol=1e-6
        )
        vertices = np.vstack(scene.faces)
        # the faces drawn lie on the ball (the fans' apexes, inside, excepted), all facing the camera
        assert np.quantile(np.abs(np.linalg.norm(vertices - [2 * t, 0, 1], axis=1) - 1), 0.9) < 1e-9
        assert 0.3 < len(scene.faces) / len(mesh.faces) < 0.7
    lengths = [len(scene.path) for (scene,) in rows]
    assert lengths == sorted(lengths) and lengths[0] == 1 and lengths[-1] == 11  # the path grows


@pytest.mark.parametrize("build", ["sphere", "torus", "rattleback"])
def test_views_follow_motion(build: str, coin) -> None:
    if build == "torus":
        body, runs = coin
        runs = runs.trajectories
    else:
        if build == "sphere":  # Routh's sphere: centre of mass below the centre
            body = rolling_body(
                Sphere(1.0), mass=1.0, inertia=[0.4, 0.4, 0.5], center_of_mass=(0, 0, -0.3), g=9.81
            )
            start = initial_state(body, R=np.eye(3), omega=[1.0, 2.0, 3.0])
        else:
            body, start = rattleback()
        runs = {m: simulate(body, m, 1.0, start, samples=21) for m in ("chaplygin", "lindelof")}
    mesh, times, rows = scenes(body, runs, snapshots=5)
    truth = {label: motion(body, run) for label, run in runs.items()}
    assert len(rows) == 5 and all([s.label for s in row] == list(runs) for row in rows)
    for j, label in enumerate(runs):
        mo = truth[label]
        column = [row[j] for row in rows]
        assert [s.index for s in column] == sorted({s.index for s in column})  # later samples, in order
        for scene in column:
            k = scene.index
            assert scene.t == mo.t[k]
            assert np.array_equal(scene.path, mo.contact[: k + 1])  # the contact path so far
            assert np.vstack(scene.faces)[:, 2].min() > -1e-6 * mesh.radius  # the body above the plane ...
            shadow = MplPath(scene.shadow[:, :2])
            assert shadow.contains_point(mo.contact[k, :2]) and shadow.contains_point(
                mo.centre[k, :2]
            )  # ... over it
        # the body turns: its marker's arm from the centre changes direction as R does
        arms = np.array([s.marker - s.centre for s in column])
        turned = np.degrees(np.arccos(np.clip(arms[-1] @ arms[0] / np.linalg.norm(arms[0]) ** 2, -1, 1)))
        R0, R1 = mo.R[column[0].index], mo.R[column[-1].index]
        expected = np.degrees(np.arccos(np.clip((np.trace(R1 @ R0.T) - 1) / 2, -1, 1)))
        assert turned <= expected + 1e-6 and (expected < 5 or turned > 1)
    fig = show_rolling(body, runs, snapshots=3)
    assert len(fig.axes) == 1 + 3 * len(runs)


def test_the_fragment_is_self_contained(coin) -> None:
    body, comparison = coin
    text = body_views(body, comparison, snapshots=3)
    assert text.startswith('<figure class="figure bodyview"') and text.count("<svg") == 1
    assert not re.search(r"<(script|link|img|image|iframe|object|embed|foreignObject)\b", text, re.I)
    refs = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)""", text, re.I)
    assert refs and all(ref.startswith("#") for ref in refs)  # in-file only: the markers' <use>
    assert not re.search(r"url\((?!#)", text) and "@import" not in text
    assert set(re.findall(r"https?://[^\s\"'<>]*", text)) <= {
        "http://www.w3.org/2000/svg",
        "http://www.w3.org/1999/xlink",
    }
    assert text.count("<path") > 500  # the bodies' faces


def test_bad_input_is_refused_with_the_key(coin) -> None:
    body, comparison = coin
    with pytest.raises(InputError, match="not built by chaplygin.bodies.rolling_body"):
        scenes(examples.rolling_sphere(), comparison)
    with pytest.raises(InputError, match="snapshots"):
        scenes(body, comparison, snapshots=0)
    with pytest.raises(InputError, match="trajectories"):
        scenes(body, [1, 2])
    assert chaplygin.show_rolling is show_rolling


# ---------------------------------------------------------------- rendering in headless Chromium
MEASURE = """<script>
(() => {
  const box = e => { const r = e.getBoundingClientRect();
                     return [r.left + scrollX, r.top + scrollY, r.width, r.height]; };
  const out = {
    page: [document.documentElement.scrollWidth, document.documentElement.scrollHeight],
    figure: box(document.querySelector('#figure-body svg')),
    // each view's frame: its axes' background patch (the group's own box holds clipped lines)
    cells: [...document.querySelectorAll('#figure-body g[id^="bodyview-"]')]
      .map(g => [g.id, box(g.querySelector('g[id^="patch"] path'))]),
  };
  const pre = document.createElement('pre');
  pre.id = 'measurements';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
</script>"""


def trimmed(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two views cut to the same size (their frames may differ by a pixel of rounding)."""
    h, w = min(a.shape[0], b.shape[0]), min(a.shape[1], b.shape[1])
    return a[:h, :w], b[:h, :w]


def lightness(pixels: np.ndarray) -> np.ndarray:
    return pixels @ np.array([0.2126, 0.7152, 0.0722])


def gold(pixels: np.ndarray) -> np.ndarray:
    """Pixels of the gold marker (the only yellow in the views): red, green well above blue."""
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return (r > 0.3) & (g > 0.55 * r) & (b < 0.35 * g)


def test_report_shows_the_body_rolling_in_chromium(coin, tmp_path: Path) -> None:
    binary = chromium()
    body, comparison = coin
    report = write_report(body, tmp_path / "coin.html", comparison=comparison)
    text = report.read_text(encoding="utf-8")
    assert '<section id="body"><h2>The body rolling</h2>' in text and text.count("<svg") == 4
    probe = tmp_path / "probe.html"
    probe.write_text(text.replace("</body>", MEASURE + "</body>"), encoding="utf-8")
    dom = run_chromium(binary, tmp_path / "profile", "--window-size=1200,1600", "--dump-dom", probe.as_uri())
    found = re.search(r'<pre id="measurements">(.*?)</pre>', dom.stdout, re.S)
    assert found, f"no measurements in Chromium's DOM dump: {dom.stderr[-2000:]}"
    m = json.loads(html.unescape(found.group(1)))
    cells = dict(m["cells"])
    assert len(cells) == 12 and m["figure"][2] > 500  # 6 times × 2 models, laid out
    shot = tmp_path / "shot.png"
    height = int(m["page"][1]) + 50
    run_chromium(
        binary, tmp_path / "profile", f"--window-size=1200,{height}", f"--screenshot={shot}", report.as_uri()
    )
    import matplotlib.image

    pixels = matplotlib.image.imread(shot)[..., :3]
    assert pixels.shape[0] >= m["figure"][1] + m["figure"][3]

    def crop(name: str) -> np.ndarray:
        x, y, w, h = (round(v) for v in cells[name])
        return pixels[y : y + h, x : x + w]

    for name in cells:
        coloured = np.ptp(crop(name), axis=2) > 0.1  # the body and the paths, not the ground, grid or shadow
        assert coloured.mean() > 0.05, f"{name}: the view is blank"

    def parted(row: int) -> float:
        """Fraction of the pixels whose lightness differs between the two models' views."""
        a, b = trimmed(*(lightness(crop(f"bodyview-{row}-{j}")) for j in (1, 2)))
        return float(np.mean(np.abs(a - b) > 0.1))

    # from one state, the same picture at t = 0 (the palettes differ in hue only); then the motions part
    assert parted(1) < 0.01 and parted(6) > 0.1
    # the body turns: its gold octant shows, and moves from view to view
    for j in (1, 2):
        marks = [gold(crop(f"bodyview-{i}-{j}")) for i in range(1, 7)]
        seen = [mark for mark in marks if mark.mean() > 0.002]
        assert len(seen) >= 3
        for a, b in itertools.pairwise(seen):
            a, b = trimmed(a, b)
            assert (a & b).sum() < 0.7 * (a | b).sum()


@pytest.mark.parametrize(
    "shape, extent",
    [
        (Ellipsoid(0.2, 0.03, 0.02), (0.2, 0.03, 0.02)),  # the rattleback: long and thin
        (Torus(1.0, 0.2), (1.2, 1.2, 0.2)),
        (Sphere(1.0), (1.0, 1.0, 1.0)),
    ],
)
def test_the_mesh_is_the_shape(shape, extent) -> None:
    mesh = surface(shape)
    # the drawn surface reaches the body's semi-axes, each way, and no further
    assert np.allclose(mesh.points.max(axis=0), extent, rtol=1e-3)
    assert np.allclose(mesh.points.min(axis=0), -np.array(extent), rtol=1e-3)
    if isinstance(shape, Ellipsoid):  # every vertex on the ellipsoid
        assert np.allclose(np.sum((mesh.points / extent) ** 2, axis=1)[:-2], 1.0)
    assert set(mesh.paint) == {0, 1, 2} and len(mesh.faces) == len(mesh.normals)
