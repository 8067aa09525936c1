"""`hconv diagnose` recovers a planted convention; `hconv compare` measures the shortcuts.

Each convention is planted with independent numpy code (numpy.linalg.solve on the tensor that
convention builds, rotations from the test helpers' own axis-angle code), never with hconv's own
hypothesis functions; the body-frame ω of a free body is also planted by MuJoCo itself.
"""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from helpers import axis_angle, hconv_inprocess, need, physical_bodies, quats, rodrigues, six, vec

from hconv.solve.options import Conventions
from hconv.tables.job import Job
from hconv.tools import diagnose, stats
from hconv.tools.stats import Summary

SIX = ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"]
N = 120


def scene(rng):
    I = physical_bodies(rng, N)  # body-frame tensors with products
    u, th = axis_angle(rng, N)
    R = rodrigues(u, th)
    return dict(
        I=I,
        R=R,
        q=quats(u, th),
        H=rng.normal(size=(N, 3)),
        r=rng.normal(size=(N, 3)),
        m=rng.uniform(0.5, 3, N),
        v=rng.normal(size=(N, 3)),
    )


def solve(T, H):
    return np.linalg.solve(T, H[..., None])[..., 0]


def world(R, T):
    return R @ T @ np.swapaxes(R, 1, 2)


def rotation_of(q):
    """The rotations ``(n, 3, 3)`` of quaternions ``(n, 4)`` (w, x, y, z), through their axis and
    angle (helpers.rodrigues), apart from any quaternion-to-matrix formula."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    s = np.linalg.norm(q[:, 1:], axis=1)
    axis = q[:, 1:] / np.where(s > 0, s, 1.0)[:, None]
    return rodrigues(axis, 2 * np.arctan2(s, q[:, 0]))


def from_six(v, order):
    """The tensor an engine builds from hconv's six numbers read in ``order``."""
    T = np.zeros((len(v), 3, 3))
    idx = {"xx": (0, 0), "yy": (1, 1), "zz": (2, 2), "xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}
    for k, e in enumerate(order):
        i, j = idx[e]
        T[:, i, j] = T[:, j, i] = v[:, k]
    return T


def plant(s, name):
    I, R, H, r, m, v = s["I"], s["R"], s["H"], s["r"], s["m"], s["v"]
    Rt = np.swapaxes(R, 1, 2)
    rb = np.einsum("nji,nj->ni", R, r)  # r in the body frame
    Hb = np.einsum("nji,nj->ni", R, H)
    if name == "exact":
        return solve(world(R, I), H)
    if name == "transposed-rotation":
        return solve(world(Rt, I), H)
    if name == "ignored-rotation":
        return solve(I, H)
    if name == "omega-body-frame":  # ω in the body frame, as MuJoCo's qvel[3:6], logged as world
        return solve(I, Hb)
    if name == "quat-xyzw":  # the file's qw, qx, qy, qz hold the engine's x, y, z, w
        return solve(world(rotation_of(s["q"][:, [3, 0, 1, 2]]), I), H)
    if name == "omega-deg-per-s":
        return solve(world(R, I), H) * 180 / np.pi
    if name == "orbital-momentum":  # H about the origin; the engine's ω is the spin's
        return solve(world(R, I), H - np.cross(r, m[:, None] * v))
    if name == "flipped-products":
        return solve(world(R, 2 * I * np.eye(3) - I), H)
    if name == "ordering-urdf":
        return solve(world(R, from_six(six(I), ("xx", "xy", "xz", "yy", "yz", "zz"))), H)
    if name == "ordering-sympy":
        return solve(world(R, from_six(six(I), ("xx", "yy", "zz", "xy", "yz", "xz"))), H)
    if name == "pivot":
        shift = m[:, None, None] * (np.sum(r * r, axis=1)[:, None, None] * np.eye(3) - np.einsum("ni,nj->nij", r, r))
        return solve(world(R, I) + shift, H)
    if name == "diagonal":
        return np.einsum("nij,nj->ni", R, Hb / np.diagonal(I, axis1=1, axis2=2))
    if name == "document":
        perp = np.sum(rb * rb, axis=1, keepdims=True) - rb * rb
        return np.einsum("nij,nj->ni", R, perp / np.diagonal(I, axis1=1, axis2=2) * Hb)
    if name == "document-principal":
        S, P = np.linalg.eigh(I)
        rp, Hp = np.einsum("nji,nj->ni", P, rb), np.einsum("nji,nj->ni", P, Hb)
        perp = np.sum(rp * rp, axis=1, keepdims=True) - rp * rp
        return np.einsum("nij,nj->ni", R @ P, perp / S * Hp)
    raise KeyError(name)


def scene_table(s, w_obs) -> pa.Table:
    return pa.table(
        {
            **vec("H", s["H"]),
            **dict(zip(SIX, six(s["I"]).T)),
            **vec("q", s["q"], "wxyz"),
            **vec("r", s["r"]),
            "m": s["m"],
            **vec("v", s["v"]),
            **{f"w{c}_obs": w_obs[:, k] for k, c in enumerate("xyz")},
        }
    )


@pytest.mark.parametrize("name", diagnose.NAMES)
def test_diagnose_names_the_planted_convention_first(rng, tmp_path, name):
    s = scene(rng)
    # an engine in float32: its ω carries float32 rounding, well inside the default tolerance
    w_obs = plant(s, name).astype(np.float32).astype(np.float64)
    pq.write_table(scene_table(s, w_obs), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"))
    assert all(x.applicable for x in d.scores)
    first, second = d.groups()[:2]
    assert [x.hypothesis for x in first] == [name]  # alone: on general rotations and tensors nothing ties
    assert first[0].residual.share_within == 1.0
    assert second[0].residual.share_within < 0.5  # the planted one is clearly apart


NEW = ("omega-body-frame", "quat-xyzw", "omega-deg-per-s", "orbital-momentum")


def test_diagnose_clean_data_is_exact_and_no_engine_mistake_explains_a_row(rng, tmp_path):
    s = scene(rng)
    pq.write_table(scene_table(s, plant(s, "exact")), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"))
    assert [x.hypothesis for x in d.groups()[0]] == ["exact"]
    share = {x.hypothesis: x.residual.share_within for x in d.scores}
    assert share["exact"] == 1.0 and all(share[n] == 0.0 for n in NEW)


def test_diagnose_json_from_the_command_line(rng, tmp_path, capsys):
    s = scene(rng)
    pq.write_table(scene_table(s, plant(s, "transposed-rotation")), tmp_path / "obs.parquet")
    proc = hconv_inprocess("diagnose", str(tmp_path / "obs.parquet"), "--json", capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    ranking = json.loads(proc.stdout)
    assert ranking[0]["hypothesis"] == "transposed-rotation" and ranking[0]["share_explained"] == 1.0
    assert set(ranking[0]) >= {"hypothesis", "median_residual", "share_explained"}
    assert ranking[0]["median_residual"] < 1e-12
    assert {r["hypothesis"] for r in ranking} == set(diagnose.NAMES)


def test_diagnose_reports_rows_nothing_explains(rng, tmp_path, capsys):
    s = scene(rng)
    w = plant(s, "exact")
    w[:7] *= 1.5  # rows a wrong engine made up
    pq.write_table(scene_table(s, w), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"))
    assert d.ranking()[0].hypothesis == "exact"
    assert d.unexplained == 7 and [e[0] for e in d.examples] == list(range(7))
    proc = hconv_inprocess("diagnose", str(tmp_path / "obs.parquet"), capsys=capsys)
    assert proc.returncode == 0 and b"7 rows no hypothesis explains" in proc.stdout


def test_diagnose_without_observed_omega_names_the_columns(tmp_path, capsys):
    pq.write_table(pa.table({"Hx": [1.0], "Hy": [0.0], "Hz": [0.0], "I": [1.0]}), tmp_path / "x.parquet")
    proc = hconv_inprocess("diagnose", str(tmp_path / "x.parquet"), capsys=capsys)
    assert proc.returncode == 3 and b"wx_obs, wy_obs, wz_obs" in proc.stderr


def test_summary_median_within_half_a_bin(rng):
    values = 10.0 ** rng.uniform(-12, 2, 10001)
    s = Summary(1e-6)
    for k in range(0, 10001, 999):
        s.add(values[k : k + 999], k)
    assert abs(s.median / np.median(values) - 1) < 0.012
    assert s.maximum == values.max() and s.max_row == int(np.argmax(values))
    assert s.within == int((values <= 1e-6).sum())


@pytest.mark.parametrize("n", [1, 2, 7, 1000, 1001])
def test_summary_median_is_numpys_on_values_that_fit(n, rng):
    """Before: the median came from the histogram alone, ±1.2 %: one row's "med diff 0.165" above
    its "max 0.165" (0.1646)."""
    values = 10.0 ** rng.uniform(-12, 2, n)
    values[rng.random(n) < 0.1] = 0.0
    with_nan = values.copy()
    with_nan[rng.random(n) < 0.1] = np.nan
    s = Summary(1e-6)
    for k in range(0, n, 97):
        s.add(with_nan[k : k + 97], k)
    answered = with_nan[~np.isnan(with_nan)]
    expected = np.median(answered) if answered.size else np.nan
    assert s.median == expected or (np.isnan(s.median) and np.isnan(expected))


def test_summary_median_past_the_kept_values_is_binned_within_min_and_max(rng, monkeypatch):
    monkeypatch.setattr(stats, "EXACT_VALUES", 100)
    values = 10.0 ** rng.uniform(-3, -1, 10001)
    s = Summary()
    for k in range(0, 10001, 999):
        s.add(values[k : k + 999], k)
    assert abs(s.median / np.median(values) - 1) < 0.012
    one = Summary()
    one.add(np.full(101, 0.1646))  # past the kept values: the bin's middle, 0.1641, is below them all
    assert one.median == 0.1646 and one.minimum == 0.1646


def test_compare_one_row_median_is_its_value(tmp_path, capsys):
    """Before: "med diff 0.164, max 0.165" and "med ° 7.16, max ° 7.13" for one row."""
    src = tmp_path / "one.csv"
    src.write_text("Hx,Hy,Hz,Ixx,Iyy,Izz,Ixy,Ixz,Iyz,rx,ry,rz\n1,2,3,1,2,3,0.3,0.2,0.1,0.1,0.2,0.3\n")
    proc = hconv_inprocess("compare", str(src), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    for line in proc.stdout.decode().splitlines()[2:10]:  # a method's row: name, med, max, row, med °, max °
        cells = line.split("\t")
        assert (cells[1], cells[4]) == (cells[2], cells[5]), line


def test_compare_writes_per_row_figures_and_finds_shortcut_failures(rng, tmp_path, capsys):
    s = scene(rng)
    t = pa.table({**vec("H", s["H"]), **dict(zip(SIX, six(world(s["R"], s["I"])).T)), **vec("r", s["r"])})
    pq.write_table(t, tmp_path / "in.parquet")
    proc = hconv_inprocess("compare", str(tmp_path / "in.parquet"), str(tmp_path / "cmp.parquet"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    out = pq.read_table(tmp_path / "cmp.parquet")
    assert out.num_rows == N and out.column_names[:12] == t.column_names
    np.testing.assert_array_equal(out.column("diff_exact").to_numpy(), 0.0)
    assert out.column("diff_lapack").to_numpy().max() < 1e-12
    # the diagonal shortcut's error grows with the off-diagonal ratio
    off, diff = out.column("offdiag").to_numpy(), out.column("diff_diagonal").to_numpy()
    assert np.median(diff[off > 0.3]) > 4 * np.median(diff[off < 0.1])
    assert b"rows where diagonal is furthest off" in proc.stdout


def diagnosed(tmp_path, table, **job):
    pq.write_table(table, tmp_path / "obs.parquet")
    return diagnose.diagnose_file(str(tmp_path / "obs.parquet"), job=Job(**job))


def first_group(d):
    return [x.hypothesis for x in d.groups()[0]]


def not_scored(d):
    return {x.hypothesis: x.why_not for x in d.scores if not x.applicable}


def equivalent(s, w_obs, tol=1e-9):
    """The hypotheses whose independent plant gives ``w_obs`` on every row: those the data cannot
    tell apart from the planted one."""
    same = set()
    for n in diagnose.NAMES:
        try:
            w = plant(s, n)
        except np.linalg.LinAlgError:  # that convention makes a singular tensor of these rows
            continue
        if (np.linalg.norm(w - w_obs, axis=1) <= tol * np.linalg.norm(w_obs, axis=1)).all():
            same.add(n)
    return same


# --- the scene options: each hypothesis is one mistake away from what the user declared


def test_diagnose_frame_body_leaves_out_what_q_would_turn(rng, tmp_path):
    s = scene(rng)
    Hb = np.einsum("nji,nj->ni", s["R"], s["H"])
    t = scene_table({**s, "H": Hb}, solve(s["I"], Hb))  # H and ω in the body frame, as M·qvel and qvel
    d = diagnosed(tmp_path, t, conventions=Conventions(frame="body"))
    assert first_group(d) == ["exact"] and d.groups()[0][0].residual.share_within == 1.0
    left = not_scored(d)
    assert set(left) == {"transposed-rotation", "ignored-rotation", "omega-body-frame", "quat-xyzw"}
    assert "q turns nothing" in left["transposed-rotation"] and "q turns nothing" in left["quat-xyzw"]


def test_diagnose_frame_body_with_omega_declared_world_finds_body_frame_omega(rng, tmp_path):
    s = scene(rng)
    Hb = np.einsum("nji,nj->ni", s["R"], s["H"])
    w_B = solve(s["I"], Hb)
    conv = Conventions(frame="body", omega_frame="world")
    d = diagnosed(tmp_path, scene_table({**s, "H": Hb}, w_B), conventions=conv)
    assert first_group(d) == ["omega-body-frame"] and d.groups()[0][0].residual.share_within == 1.0
    assert "omega-body-frame" in not_scored(d)["ignored-rotation"]  # not turning ω is that hypothesis
    w_W = np.einsum("nij,nj->ni", s["R"], w_B)
    assert first_group(diagnosed(tmp_path, scene_table({**s, "H": Hb}, w_W), conventions=conv)) == ["exact"]


def test_diagnose_omega_frame_body_declared_makes_exact_of_body_frame_omega(rng, tmp_path):
    s = scene(rng)
    d = diagnosed(tmp_path, scene_table(s, plant(s, "omega-body-frame")), conventions=Conventions(omega_frame="body"))
    assert first_group(d) == ["exact"] and d.groups()[0][0].residual.share_within == 1.0
    assert not_scored(d) == {"omega-body-frame": "ω is declared in the body frame"}


def test_diagnose_about_free_finds_the_orbital_term_taken_for_spin(rng, tmp_path):
    s = scene(rng)
    H_O = s["H"] + np.cross(s["r"], s["m"][:, None] * s["v"])  # about the origin; s["H"] is the spin
    wrong = solve(world(s["R"], s["I"]), H_O)  # the engine took all of H_O for spin
    d = diagnosed(tmp_path, scene_table({**s, "H": H_O}, wrong), conventions=Conventions(about="free"))
    assert first_group(d) == ["orbital-momentum"] and d.groups()[0][0].residual.share_within == 1.0
    assert "left in H" in next(x.summary for x in d.scores if x.hypothesis == "orbital-momentum")
    right = solve(world(s["R"], s["I"]), s["H"])
    d = diagnosed(tmp_path, scene_table({**s, "H": H_O}, right), conventions=Conventions(about="free"))
    assert first_group(d) == ["exact"]


def test_diagnose_without_v_says_orbital_momentum_needs_it(rng, tmp_path):
    s = scene(rng)
    t = scene_table(s, plant(s, "exact")).drop_columns(["vx", "vy", "vz"])
    assert not_scored(diagnosed(tmp_path, t)) == {"orbital-momentum": "needs v"}


def test_diagnose_products_positive_declared_flips_the_hypothesis(rng, tmp_path):
    s = scene(rng)
    conv = Conventions(products="positive")
    assert first_group(diagnosed(tmp_path, scene_table(s, plant(s, "exact")), conventions=conv)) == ["flipped-products"]
    assert first_group(diagnosed(tmp_path, scene_table(s, plant(s, "flipped-products")), conventions=conv)) == ["exact"]


def test_diagnose_omega_declared_in_degrees(rng, tmp_path):
    s = scene(rng)
    d = diagnosed(tmp_path, scene_table(s, plant(s, "omega-deg-per-s")), unit_options={"w_obs": "deg/s"})
    assert first_group(d) == ["exact"] and not_scored(d) == {}
    # declared rpm: rpm numbers are exact, and degrees per second are the mistake
    rpm = plant(s, "exact") * 60 / (2 * np.pi)
    d = diagnosed(tmp_path, scene_table(s, rpm), unit_options={"w_obs": "rpm"})
    assert first_group(d) == ["exact"]
    d = diagnosed(tmp_path, scene_table(s, plant(s, "omega-deg-per-s")), unit_options={"w_obs": "rpm"})
    assert first_group(d) == ["omega-deg-per-s"] and d.groups()[0][0].residual.share_within == 1.0


def test_diagnose_omega_in_rad_per_s_declared_deg_per_s_is_the_reverse_slip(rng, tmp_path):
    """The mirror of omega-deg-per-s: the engine's rad/s numbers, declared deg/s, read as π/180
    of the true ω. Before, omega-deg-per-s was not scored under deg/s and nothing explained them."""
    s = scene(rng)
    rad = plant(s, "exact").astype(np.float32).astype(np.float64)  # the numbers as a float32 engine logs them
    d = diagnosed(tmp_path, scene_table(s, rad), unit_options={"w_obs": "deg/s"})
    assert first_group(d) == ["omega-deg-per-s"] and d.groups()[0][0].residual.share_within == 1.0
    assert d.groups()[1][0].residual.share_within < 0.5
    best = d.groups()[0][0]
    assert best.summary == "ω logged in rad/s but declared deg/s (--unit w_obs=deg/s)"
    # declared in rad/s, as by default, the hypothesis is the forward slip again
    d = diagnosed(tmp_path, scene_table(s, rad))
    assert first_group(d) == ["exact"] and next(x for x in d.scores if x.hypothesis == "omega-deg-per-s").summary == (
        "ω logged in degrees per second"
    )


def test_diagnose_quat_list_read_as_xyzw_leaves_out_quat_xyzw(rng, tmp_path):
    s = scene(rng)
    t = scene_table(s, plant(s, "exact")).drop_columns(["qw", "qx", "qy", "qz"])
    xyzw = s["q"][:, [1, 2, 3, 0]]
    t = t.append_column("q", pa.FixedSizeListArray.from_arrays(pa.array(xyzw.ravel()), 4))
    d = diagnosed(tmp_path, t, quat_order="xyzw")
    assert first_group(d) == ["exact"] and "--quat-order xyzw" in not_scored(d)["quat-xyzw"]
    # the same list read as w, x, y, z is the mistake quat-xyzw names
    d = diagnosed(tmp_path, t)
    assert first_group(d) == ["quat-xyzw"] and d.groups()[0][0].residual.share_within == 1.0


def test_diagnose_quat_xyzw_names_where_q_is(rng, tmp_path):
    """Before: with a list column q, quat-xyzw still said "in the qw, qx, qy, qz columns"."""
    s = scene(rng)
    t = scene_table(s, plant(s, "quat-xyzw"))
    summary = next(x for x in diagnosed(tmp_path, t).scores if x.hypothesis == "quat-xyzw").summary
    assert summary.endswith("in the qw, qx, qy, qz columns")
    t = t.drop_columns(["qw", "qx", "qy", "qz"])
    t = t.append_column("q", pa.FixedSizeListArray.from_arrays(pa.array(s["q"].ravel()), 4))
    summary = next(x for x in diagnosed(tmp_path, t).scores if x.hypothesis == "quat-xyzw").summary
    assert summary.endswith("in the list column q (read as w, x, y, z)") and "qw" not in summary


# --- ties: where the data cannot tell hypotheses apart, they share the first rank


def planar(rng):
    """Bodies turning about world z only, z a principal axis, H along z: a planar log."""
    s = scene(rng)
    u = np.tile([0.0, 0.0, 1.0], (N, 1))
    th = rng.uniform(-np.pi, np.pi, N)
    Rz = rodrigues(u, th)
    I = s["I"].copy()
    I[:, 0, 2] = I[:, 2, 0] = I[:, 1, 2] = I[:, 2, 1] = 0.0
    H = np.zeros((N, 3))
    H[:, 2] = rng.normal(size=N)
    return {**s, "I": I, "R": Rz, "q": quats(u, th), "H": H}


def special_rotation(rng):
    """Every row turned 120° about (1, 1, 1): q = (½, ½, ½, ½), the same in any order."""
    s = scene(rng)
    u = np.tile(np.ones(3) / np.sqrt(3), (N, 1))
    th = np.full(N, 2 * np.pi / 3)
    return {**s, "R": rodrigues(u, th), "q": quats(u, th)}


def diagonal_tensors(rng):
    s = scene(rng)
    return {**s, "I": s["I"] * np.eye(3)}


@pytest.mark.parametrize(
    "make, name, tied",
    [
        (
            planar,
            "omega-body-frame",
            {"exact", "transposed-rotation", "ignored-rotation", "omega-body-frame"}
            | {"flipped-products", "ordering-sympy", "diagonal"},
        ),
        (special_rotation, "quat-xyzw", {"exact", "quat-xyzw"}),
        (diagonal_tensors, "exact", {"exact", "flipped-products", "ordering-sympy", "diagonal"}),
    ],
    ids=["planar", "special-rotation", "diagonal-tensor"],
)
def test_diagnose_ties_what_the_data_cannot_tell_apart(rng, tmp_path, make, name, tied, capsys):
    s = make(rng)
    w_obs = plant(s, name)
    assert equivalent(s, w_obs) == tied  # the test's own reckoning of what is the same on this data
    pq.write_table(scene_table(s, w_obs), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"))
    top = d.groups()[0]
    assert {x.hypothesis for x in top} == tied and all(x.residual.share_within == 1.0 for x in top)
    assert [x.hypothesis for x in top] == [n for n in diagnose.NAMES if n in tied]  # not ranked by noise
    ranks = {x.hypothesis: (rank, set(others)) for rank, x, others in d.ranks()}
    assert all(ranks[n] == (1, tied - {n}) for n in tied)
    assert min(r for r, _ in ranks.values() if r > 1) == len(tied) + 1

    proc = hconv_inprocess("diagnose", str(tmp_path / "obs.parquet"), "--json", capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    got = json.loads(proc.stdout)
    assert {r["hypothesis"] for r in got if r["rank"] == 1} == tied
    assert all(set(r["tied_with"]) == tied - {r["hypothesis"]} for r in got if r["rank"] == 1)
    text = hconv_inprocess("diagnose", str(tmp_path / "obs.parquet"), capsys=capsys).stdout.decode()
    names = ", ".join(n for n in diagnose.NAMES if n in tied)
    assert f"# tied for best, explaining the same rows with the same ω (to the data's precision): {names}" in text
    assert "# best:" not in text
    assert sorted(line.split("\t")[0] for line in text.splitlines() if "\t" in line)[: len(tied)] == ["1"] * len(tied)


@pytest.mark.parametrize("float32", [False, True], ids=["float64", "float32"])
def test_diagnose_ties_need_the_same_omega_not_both_within_tol(rng, tmp_path, float32):
    """A newcomer's --tol 2 tied exact matches with hypotheses 10 % off, as both were within tol;
    a tie is the same ω to the data's precision: a few ulps for float64 ω_obs, float32's rounding
    for an engine in float32."""
    s = diagonal_tensors(rng)
    w_obs = plant(s, "exact")
    if float32:
        w_obs = w_obs.astype(np.float32).astype(np.float64)
    tied = {"exact", "flipped-products", "ordering-sympy", "diagonal"}
    assert equivalent(s, w_obs, tol=1e-6) == tied  # the test's own reckoning, as above
    pq.write_table(scene_table(s, w_obs), tmp_path / "obs.parquet")
    d = diagnose.diagnose_file(str(tmp_path / "obs.parquet"), tol=2.0)
    groups = d.groups()
    assert {x.hypothesis for x in groups[0]} == tied
    # transposed-rotation, quat-xyzw, ignored-rotation ... explain every row at tol 2, each its own ω
    assert [len(g) for g in groups[1:4]] == [1, 1, 1] and all(g[0].residual.share_within == 1.0 for g in groups[1:4])
    for g in groups:  # tied, the same ω: the same residuals (document and its principal form, here)
        assert np.allclose([x.residual.median for x in g], g[0].residual.median, rtol=1e-6, equal_nan=True)


# --- MuJoCo itself: a free body's qvel[3:6] is its body-frame ω


FULLINERTIA = (0.30, 0.22, 0.12, 0.03, -0.02, 0.05)  # xx, yy, zz, xy, xz, yz: MuJoCo's order is hconv's


def mujoco_log(episodes=4, samples=40):
    """A tumbling free body simulated by MuJoCo: per sample, qpos[3:7], the world-frame H about
    the centre of mass (subtree_angmom), the body-frame M·qvel[3:6] and qvel[3:6]."""
    mujoco = need("mujoco")
    xml = (
        "<mujoco><option gravity='0 0 0' timestep='0.002'/><worldbody><body name='b' pos='0.3 -0.2 1'>"
        f"<freejoint/><inertial pos='0 0 0' mass='2' fullinertia='{' '.join(map(str, FULLINERTIA))}'/>"
        "</body></worldbody></mujoco>"
    )
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    rows = []
    for _ in range(episodes):
        mujoco.mj_resetData(m, d)
        q = rng.normal(size=4)
        d.qpos[3:7] = q / np.linalg.norm(q)
        d.qvel[:] = rng.normal(size=6) * 3
        for _ in range(samples):
            for _ in range(25):
                mujoco.mj_step(m, d)
            mujoco.mj_forward(m, d)
            mujoco.mj_subtreeVel(m, d)
            m_qvel = np.zeros(m.nv)
            mujoco.mj_mulM(m, d, m_qvel, d.qvel)
            rows.append((d.qpos[3:7].copy(), d.subtree_angmom[1].copy(), m_qvel[3:6], d.qvel[3:6].copy()))
    q, H_W, H_B, w_B = (np.array(x) for x in zip(*rows))
    return q, H_W, H_B, w_B


def mujoco_table(q, H, w_obs):
    n = len(q)
    return pa.table(
        {
            **vec("q", q, "wxyz"),
            **dict(zip(SIX, (np.full(n, x) for x in FULLINERTIA))),
            **vec("H", H),
            **{f"w{c}_obs": w_obs[:, k] for k, c in enumerate("xyz")},
        }
    )


def test_diagnose_mujoco_free_joint_qvel_is_omega_body_frame(tmp_path):
    q, H_W, H_B, w_B = mujoco_log()
    # MuJoCo's own H about the centre of mass in the world frame, with qvel[3:6] logged as world ω
    d = diagnosed(tmp_path, mujoco_table(q, H_W, w_B))
    assert first_group(d) == ["omega-body-frame"]
    top = d.groups()[0][0]
    assert top.residual.share_within == 1.0 and top.residual.maximum < 1e-9
    assert next(x for x in d.scores if x.hypothesis == "exact").residual.share_within == 0.0
    # the fix it points to: ω declared in the body frame
    d = diagnosed(tmp_path, mujoco_table(q, H_W, w_B), conventions=Conventions(omega_frame="body"))
    assert first_group(d) == ["exact"] and d.groups()[0][0].residual.share_within == 1.0
    # M·qvel is body-frame H: with --frame body it is exact, with ω declared world it is the mistake
    d = diagnosed(tmp_path, mujoco_table(q, H_B, w_B), conventions=Conventions(frame="body"))
    assert first_group(d) == ["exact"] and d.groups()[0][0].residual.share_within == 1.0
    d = diagnosed(tmp_path, mujoco_table(q, H_B, w_B), conventions=Conventions(frame="body", omega_frame="world"))
    assert first_group(d) == ["omega-body-frame"] and d.groups()[0][0].residual.share_within == 1.0


def test_diagnose_scene_options_from_the_command_line(rng, tmp_path, capsys):
    s = scene(rng)
    Hb = np.einsum("nji,nj->ni", s["R"], s["H"])
    pq.write_table(scene_table({**s, "H": Hb}, solve(s["I"], Hb)), tmp_path / "obs.parquet")
    proc = hconv_inprocess(
        "diagnose", str(tmp_path / "obs.parquet"), "--frame", "body", "--omega-frame", "world", "--json", capsys=capsys
    )
    assert proc.returncode == 0, proc.stderr.decode()
    got = json.loads(proc.stdout)
    assert got[0]["hypothesis"] == "omega-body-frame" and got[0]["rank"] == 1 and got[0]["tied_with"] == []
    assert got[0]["share_explained"] == 1.0
    proc = hconv_inprocess("diagnose", str(tmp_path / "obs.parquet"), "--frame", "body", capsys=capsys)
    assert proc.returncode == 0 and b"# best: exact" in proc.stdout
    assert (
        b"transposed-rotation, quat-xyzw (H and \xcf\x89 are declared in the body frame, so q turns nothing)"
        in proc.stdout
    )
    proc = hconv_inprocess("diagnose", str(tmp_path / "obs.parquet"), "--about", "free", capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()


def test_diagnose_degenerate_options_from_the_command_line(rng, tmp_path, capsys):
    """Thin rods, whose engine drops the axis of the (near-)zero moment: convert took --degenerate
    and --degenerate-rtol, diagnose did not, so exact could not explain such a log."""
    s = scene(rng)
    moments = rng.uniform(0.5, 2.0, (N, 2))
    I = np.zeros((N, 3, 3))
    I[:, 0, 0], I[:, 1, 1] = moments[:, 0], moments[:, 1]
    I[:, 2, 2] = 1e-10 * moments.sum(axis=1)  # a rod along body z, nearly: not singular in float64
    R = s["R"]
    H_B = np.einsum("nji,nj->ni", R, s["H"])
    w_B = np.zeros((N, 3))
    w_B[:, :2] = H_B[:, :2] / moments  # the pseudo-inverse: nothing about the rod's own axis
    w_obs = np.einsum("nij,nj->ni", R, w_B)
    pq.write_table(scene_table({**s, "I": I}, w_obs), tmp_path / "rods.parquet")
    proc = hconv_inprocess(
        "diagnose",
        str(tmp_path / "rods.parquet"),
        "--degenerate",
        "pinv",
        "--degenerate-rtol",
        "1e-6",
        "--json",
        capsys=capsys,
    )
    assert proc.returncode == 0, proc.stderr.decode()
    got = json.loads(proc.stdout)
    assert got[0]["hypothesis"] == "exact" and got[0]["share_explained"] == 1.0
    plain = json.loads(hconv_inprocess("diagnose", str(tmp_path / "rods.parquet"), "--json", capsys=capsys).stdout)
    assert next(r for r in plain if r["hypothesis"] == "exact")["share_explained"] == 0.0


def test_diagnose_of_no_rows_calls_nothing_best(tmp_path, capsys):
    (tmp_path / "empty.csv").write_text("Hx,Hy,Hz,I,wx_obs,wy_obs,wz_obs\n")
    proc = hconv_inprocess("diagnose", str(tmp_path / "empty.csv"), capsys=capsys)
    assert proc.returncode == 0, proc.stderr.decode()
    assert b"# hconv diagnose \xc2\xb7 0 rows" in proc.stdout
    assert b"best" not in proc.stdout and b"closest" not in proc.stdout


@pytest.mark.parametrize("tol", [float("inf"), float("nan"), 0.0])
def test_diagnose_file_tol_not_positive_and_finite_is_refused(tol, tmp_path):
    """Before: tol=inf passed and called every hypothesis an explanation of every row."""
    from hconv.errors import UsageError

    with pytest.raises(UsageError, match=rf"^tol must be a positive finite number, got {tol}$"):
        diagnose.diagnose_file(str(tmp_path / "obs.parquet"), tol=tol)
