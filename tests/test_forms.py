"""Inertia in the form the scene has it, orientations and frames, against independent references.

References: a 50-digit mpmath solve of the full world-frame tensor, rotations built from
axis and angle by Rodrigues' formula (not from hconv's quaternion code), and analytic bodies.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from helpers import axis_angle, mp_solve, physical_bodies, quats, rel_err, rodrigues, six, table, vec, w_of

import hconv
from hconv.errors import InputError, UsageError
from hconv.solve import status
from hconv.solve.options import Conventions
from hconv.tables.job import Job


def principal_scene(rng, n):
    """Principal moments ``(n, 3)`` obeying the triangle inequality, orientations, and world H."""
    c = rng.uniform(0.05, 1.0, (n, 3))
    moments = np.stack([c[:, 1] + c[:, 2], c[:, 0] + c[:, 2], c[:, 0] + c[:, 1]], axis=1)
    u, theta = axis_angle(rng, n)
    return moments, rodrigues(u, theta), quats(u, theta), rng.normal(size=(n, 3))


# --- every form gives the six-number form's answer ----------------------------------------


def test_convert_principal_with_quaternion_matches_world_tensor(rng):
    moments, R, q, H = principal_scene(rng, 200)
    I_world = np.einsum("nij,nj,nkj->nik", R, moments, R)  # R·diag·Rᵀ
    want = mp_solve(I_world, H)
    t = table(**vec("H", H), I1=moments[:, 0], I2=moments[:, 1], I3=moments[:, 2], **vec("q", q, "wxyz"))
    got = hconv.convert_table(t)
    assert set(got.column("status").to_pylist()) == {"ok"}
    assert rel_err(w_of(got), want).max() < 1e-14
    # the six-number form of the same world tensor, without q, agrees
    six_t = table(**vec("H", H), **dict(zip(["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"], six(I_world).T)))
    assert rel_err(w_of(hconv.convert_table(six_t)), want).max() < 1e-14


def test_convert_quaternion_rotates_body_to_world_as_jolt_and_mujoco():
    # q = (1/2, 1/2, 1/2, 1/2) turns 120° about (1, 1, 1): body x → world y, y → z, z → x. Body
    # moments (1, 2, 3); H along world x lies along body z, so ω = H / 3 along world x. The
    # transposed rotation would put it along body y and give H / 2.
    t = table(Hx=[1.0], Hy=[0.0], Hz=[0.0], I1=[1.0], I2=[2.0], I3=[3.0], qw=[0.5], qx=[0.5], qy=[0.5], qz=[0.5])
    np.testing.assert_allclose(w_of(hconv.convert_table(t))[0], [1 / 3, 0, 0], atol=1e-16)
    t = t.set_column(t.column_names.index("qw"), "qw", pa.array([-0.5]))  # the inverse turn: body y
    t = t.set_column(t.column_names.index("qx"), "qx", pa.array([0.5]))
    np.testing.assert_allclose(w_of(hconv.convert_table(t))[0], [1 / 2, 0, 0], atol=1e-16)


def test_convert_scalar_form_is_h_over_i():
    t = table(Hx=[2.0, 0.0], Hy=[4.0, 0.0], Hz=[-6.0, 0.0], I=[2.0, 0.0])
    got = hconv.convert_table(t)
    np.testing.assert_array_equal(w_of(got)[0], [1.0, 2.0, -3.0])
    assert got.column("status").to_pylist() == ["ok", "singular"]
    assert got.column("cond").to_pylist()[0] == 1.0


def test_convert_nine_numbers_match_six_and_flag_asymmetry(rng):
    I = physical_bodies(rng, 50)
    H = rng.normal(size=(50, 3))
    nine = {f"I{a}{b}": I[:, i, j] for i, a in enumerate("xyz") for j, b in enumerate("xyz")}
    got = hconv.convert_table(table(**vec("H", H), **nine))
    assert rel_err(w_of(got), mp_solve(I, H)).max() < 1e-14
    nine["Iyx"] = nine["Iyx"] * (1 + 1e-6)
    flagged = hconv.convert_table(table(**vec("H", H), **nine)).column("status").to_pylist()
    assert set(flagged) == {"not_symmetric"}


def test_convert_list_columns_match_named_columns(rng):
    I = physical_bodies(rng, 40)
    H = rng.normal(size=(40, 3))
    named = hconv.convert_table(table(**vec("H", H), **dict(zip(["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"], six(I).T))))
    for size, values in ((6, six(I)), (9, I.reshape(40, 9))):
        t = pa.table(
            {
                "H": pa.FixedSizeListArray.from_arrays(pa.array(H.ravel()), 3),
                "I": pa.FixedSizeListArray.from_arrays(pa.array(values.ravel()), size),
            }
        )
        np.testing.assert_allclose(w_of(hconv.convert_table(t)), w_of(named), rtol=1e-15, atol=0)
    # variable-length lists of a constant length work too
    t = pa.table({"H": pa.array(H.tolist()), "I": pa.array(six(I).tolist())})
    np.testing.assert_allclose(w_of(hconv.convert_table(t)), w_of(named), rtol=1e-15, atol=0)


@pytest.mark.parametrize("order", ["wxyz", "xyzw"])
def test_convert_quaternion_list_order_option(rng, order):
    moments, R, q, H = principal_scene(rng, 30)
    want = mp_solve(np.einsum("nij,nj,nkj->nik", R, moments, R), H)
    qlist = q if order == "wxyz" else q[:, [1, 2, 3, 0]]
    t = pa.table(
        {
            "H": pa.FixedSizeListArray.from_arrays(pa.array(H.ravel()), 3),
            "I": pa.FixedSizeListArray.from_arrays(pa.array(moments.ravel()), 3),
            "q": pa.FixedSizeListArray.from_arrays(pa.array(qlist.ravel()), 4),
        }
    )
    got = hconv.convert_table(t, job=Job(quat_order=order))
    assert rel_err(w_of(got), want).max() < 1e-14


def test_convert_map_reads_other_column_names(rng):
    I = physical_bodies(rng, 10)
    H = rng.normal(size=(10, 3))
    t = table(Lx=H[:, 0], Ly=H[:, 1], Lz=H[:, 2], **dict(zip(["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"], six(I).T)))
    got = hconv.convert_table(t, job=Job(mapping=(("Hx", "Lx"), ("Hy", "Ly"), ("Hz", "Lz"))))
    assert got.column_names[:3] == ["Lx", "Ly", "Lz"]  # pass-through keeps the user's names
    assert rel_err(w_of(got), mp_solve(I, H)).max() < 1e-14


@pytest.mark.parametrize(
    "cols, needle",
    [
        ({"I1": 1, "I2": 1, "I3": 1, "Ixx": 1, "Iyy": 1, "Izz": 1, "Ixy": 0, "Ixz": 0, "Iyz": 0}, "more than one form"),
        ({"I": 1, "I1": 1, "I2": 1, "I3": 1}, "more than one form"),
        ({"I1": 1, "I2": 1}, "not I3"),
        ({"Ixx": 1, "Iyy": 1, "Izz": 1, "Ixy": 0, "Ixz": 0, "Iyz": 0, "Iyx": 0}, "not Izx, Izy"),
        ({"Hq": 1}, "missing the inertia"),
        ({"I": 1, "qw": 1, "qx": 0}, "not qy, qz"),
    ],
)
def test_plan_ambiguous_or_partial_inertia_is_one_clear_error(cols, needle):
    t = table(Hx=[1.0], Hy=[0.0], Hz=[0.0], **{k: [float(v)] for k, v in cols.items()})
    with pytest.raises(InputError, match=needle):
        hconv.convert_table(t)


def test_plan_list_column_of_wrong_length_is_named():
    t = pa.table({"H": pa.array([[1.0, 2.0, 3.0]]), "I": pa.array([[1.0, 2.0, 3.0, 4.0]])})
    with pytest.raises(InputError, match="'I' holds 4 values"):
        hconv.convert_table(t)
    t = pa.table({"H": pa.array([[1.0, 2.0, 3.0], [1.0, 2.0]]), "I": pa.array([[1.0, 2.0, 3.0]] * 2)})
    with pytest.raises(InputError, match="'H' holds 2 values in row 2, but H needs 3"):
        hconv.convert_table(t)


def test_plan_map_to_missing_column_is_named():
    t = table(Hx=[1.0], Hy=[0.0], Hz=[0.0], I=[1.0])
    with pytest.raises(InputError, match="no column 'Lx'"):
        hconv.convert_table(t, job=Job(mapping=(("Hx", "Lx"),)))
    with pytest.raises(UsageError, match="no column 'Hw'"):
        hconv.convert_table(t, job=Job(mapping=(("Hw", "Hx"),)))


# --- frames -------------------------------------------------------------------------------


def test_convert_rotated_scene_gives_rotated_answer(rng):
    # One body tensor, seen from two world frames that differ by a rotation Q: ω turns with Q.
    I_body = six(physical_bodies(rng, 100))
    u, th = axis_angle(rng, 100)
    q = quats(u, th)
    H = rng.normal(size=(100, 3))
    base = dict(**vec("H", H), **dict(zip(["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"], I_body.T)), **vec("q", q, "wxyz"))
    w1 = w_of(hconv.convert_table(table(**base)))
    u2, th2 = axis_angle(rng, 1)
    Q, q2 = rodrigues(u2, th2)[0], quats(u2, th2)[0]
    # the same bodies in the turned world: orientation q2·q, momentum Q·H
    w_, x_, y_, z_ = q2
    left = np.array([[w_, -x_, -y_, -z_], [x_, w_, -z_, y_], [y_, z_, w_, -x_], [z_, -y_, x_, w_]])
    turned = dict(base, **vec("H", H @ Q.T), **vec("q", q @ left.T, "wxyz"))
    w2 = w_of(hconv.convert_table(table(**turned)))
    assert rel_err(w2, w1 @ Q.T).max() < 1e-13


def test_convert_body_frame_input_and_world_frame_output(rng):
    moments, R, q, H_world = principal_scene(rng, 50)
    want_world = mp_solve(np.einsum("nij,nj,nkj->nik", R, moments, R), H_world)
    H_body = np.einsum("nji,nj->ni", R, H_world)  # Rᵀ·H
    cols = dict(**vec("H", H_body), I1=moments[:, 0], I2=moments[:, 1], I3=moments[:, 2], **vec("q", q, "wxyz"))
    body = hconv.convert_table(table(**cols), job=Job(conventions=Conventions(frame="body")))
    assert rel_err(w_of(body), np.einsum("nji,nj->ni", R, want_world)).max() < 1e-14
    world = hconv.convert_table(table(**cols), job=Job(conventions=Conventions(frame="body", omega_frame="world")))
    assert rel_err(w_of(world), want_world).max() < 1e-14


def test_convert_bad_quaternion_row_is_invalid_input_others_kept():
    t = table(
        Hx=[1.0, 1.0, 1.0],
        Hy=[0.0] * 3,
        Hz=[0.0] * 3,
        I=[2.0] * 3,
        qw=[1.0, 0.0, np.nan],
        qx=[0.0] * 3,
        qy=[0.0] * 3,
        qz=[0.0] * 3,
    )
    got = hconv.convert_table(t)
    assert got.column("status").to_pylist() == ["ok", "invalid_input", "invalid_input"]
    assert got.column("wx").to_pylist()[0] == 0.5


def test_convert_other_omega_frame_without_quaternion_is_an_error():
    t = table(Hx=[1.0], Hy=[0.0], Hz=[0.0], I=[2.0])
    with pytest.raises(InputError, match="needs the orientation q"):
        hconv.convert_table(t, job=Job(conventions=Conventions(omega_frame="body")))


def test_convert_positive_products_are_negated(rng):
    I = physical_bodies(rng, 30)
    H = rng.normal(size=(30, 3))
    s6 = six(I)
    cad = np.concatenate([s6[:, :3], -s6[:, 3:]], axis=1)  # what a CAD report lists
    t = table(**vec("H", H), **dict(zip(["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"], cad.T)))
    got = hconv.convert_table(t, job=Job(conventions=Conventions(products="positive")))
    assert rel_err(w_of(got), mp_solve(I, H)).max() < 1e-14
    assert rel_err(w_of(hconv.convert_table(t)), mp_solve(I, H)).min() > 1e-3  # without it: wrong


# --- the forms registry ----------------------------------------------------------------------


def _form_values(name: str, M: np.ndarray) -> np.ndarray:
    """Independent spellings of tensors ``M`` ``(N, 3, 3)`` in each of hconv's forms, ``(k, N)``
    (the diagonal forms take M's diagonal, so M must be diagonal for them)."""
    if name == "scalar":
        return M[:, 0, 0][None]
    if name == "principal":
        return np.stack([M[:, 0, 0], M[:, 1, 1], M[:, 2, 2]])
    if name == "sym6":
        return six(M).T
    return M.reshape(-1, 9).T  # full9: row-major


def _tensors_for(name: str, rng, n: int) -> np.ndarray:
    if name == "scalar":
        return np.eye(3) * rng.uniform(0.5, 2.0, (n, 1, 1))
    if name == "principal":
        c = rng.uniform(0.05, 1.0, (n, 3))
        return np.stack([np.diag(d) for d in np.stack([c[:, 1] + c[:, 2], c[:, 0] + c[:, 2], c[:, 0] + c[:, 1]], 1)])
    return physical_bodies(rng, n)


@pytest.mark.parametrize("name", ["scalar", "principal", "sym6", "full9"])
def test_form_as_sym3_solves_to_the_matrix_answer(name, rng):
    from hconv.solve import forms
    from hconv.solve.convert import convert_columns

    M, H = _tensors_for(name, rng, 40), rng.normal(size=(40, 3))
    form = forms.get(name)
    I, asym = form.as_sym3(_form_values(name, M), status.SYMMETRY_RTOL)
    assert not asym.any() and all(c.flags.c_contiguous for c in I)
    got = convert_columns(H.T, form, _form_values(name, M)).w
    assert rel_err(got, mp_solve(M, H)).max() < 4 * np.finfo(float).eps * 20


def test_form_nine_numbers_flag_asymmetry_relative_to_the_largest_entry():
    from hconv.solve import forms

    M = np.tile(np.diag([1e6, 2e6, 3e6]), (5, 1, 1))
    M[1, 0, 2] += 1e-7  # 1e-13 of the largest entry: within SYMMETRY_RTOL
    M[2, 2, 1] += 1e-5  # 3e-12 of it: beyond
    # the largest entry off the diagonal: 1e-13 of it is symmetric, 3e-12 is not, though both
    # are far beyond the tolerance of the diagonal alone
    M[3:, 0, 1] = M[3:, 1, 0] = 1e8
    M[3, 0, 1] += 1e-5
    M[4, 0, 1] += 3e-4
    I, asym = forms.get("full9").as_sym3(_form_values("full9", M), status.SYMMETRY_RTOL)
    assert asym.tolist() == [False, False, True, False, True] and I.yz[2] == 0.5e-5


def test_forms_from_array_reads_the_stacked_layouts():
    from hconv.solve import forms

    for shape, name in (((5, 3), "principal"), ((5, 6), "sym6"), ((5, 3, 3), "full9")):
        form, values = forms.from_array(np.zeros(shape))
        assert form.name == name and values.shape == (form.count, 5)
    with pytest.raises(ValueError, match=r"Expected I to have shape .*got \(5, 4\)"):
        forms.from_array(np.zeros((5, 4)))


@pytest.mark.parametrize("name", ["scalar", "principal", "sym6", "full9"])
def test_form_trace_offdiag_and_products_flip(name, rng):
    from hconv.solve import forms

    M = _tensors_for(name, rng, 30)
    form, I = forms.get(name), _form_values(name, M)
    np.testing.assert_allclose(form.trace(I), np.abs(np.trace(M, axis1=1, axis2=2)), rtol=1e-15)
    d = np.sqrt(np.abs(np.einsum("nii->ni", M)))
    ratio = np.abs(M) / (d[:, :, None] * d[:, None, :])
    ratio[:, [0, 1, 2], [0, 1, 2]] = 0
    np.testing.assert_allclose(form.offdiag(I), ratio.max(axis=(1, 2)), rtol=1e-15)
    flipped = M * np.where(np.eye(3, dtype=bool), 1.0, -1.0)
    np.testing.assert_array_equal(form.flip_products(I), _form_values(name, flipped))


@pytest.mark.parametrize("name", ["scalar", "principal", "sym6", "full9"])
def test_form_shifted_is_the_parallel_axis_theorem(name, rng):
    from hconv.kernels.frames import shift_to_pivot
    from hconv.kernels.inertia import Sym3
    from hconv.solve import forms

    n = 25
    M, m, r = _tensors_for(name, rng, n), rng.uniform(0.1, 5, n), rng.normal(size=(n, 3))
    zero = np.zeros(n)
    new_name, I_P = forms.get(name).shifted(_form_values(name, M), shift_to_pivot(Sym3(*[zero] * 6), m, r.T))
    # I_P = I_C + m·(|r|²·E − r·rᵀ), written out independently
    expect = M + m[:, None, None] * (
        np.einsum("ni,ni->n", r, r)[:, None, None] * np.eye(3) - np.einsum("ni,nj->nij", r, r)
    )
    np.testing.assert_allclose(_form_values(new_name, expect), I_P, rtol=1e-14, atol=1e-14)


def test_forms_lookup_by_name_count_and_list_size():
    from hconv.solve import forms

    assert [forms.by_count(k).name for k in (1, 3, 6, 9)] == ["scalar", "principal", "sym6", "full9"]
    assert forms.by_list_size(6).name == "sym6" and forms.by_list_size(4) is None and forms.by_count(2) is None
    with pytest.raises(UsageError, match="unknown inertia form 'sym7'; choose one of: scalar, principal"):
        forms.get("sym7")


def test_register_one_entry_is_read_mapped_and_named(monkeypatch, rng):
    """A new form (URDF's lower-case six) is one registry entry: reading, --map and the messages
    follow by themselves."""
    import dataclasses

    from hconv.solve import forms

    urdf = dataclasses.replace(
        forms.get("sym6"),
        name="urdf",
        columns=("ixx", "iyy", "izz", "ixy", "ixz", "iyz"),
        description="ixx, iyy, izz, ixy, ixz, iyz (URDF)",
        note="URDF",
    )
    monkeypatch.setitem(forms.FORMS, "urdf", urdf)
    M, H = physical_bodies(rng, 20), rng.normal(size=(20, 3))
    upper = table(**vec("H", H), **dict(zip(forms.SIX, six(M).T)))
    lower = table(**vec("H", H), **dict(zip(urdf.columns, six(M).T)))
    np.testing.assert_array_equal(w_of(hconv.convert_table(lower)), w_of(hconv.convert_table(upper)))
    renamed = table(**vec("H", H), **dict(zip(["a", "b", "c", "d", "e", "f"], six(M).T)))
    job = Job(mapping=tuple(zip(urdf.columns, "abcdef")))
    np.testing.assert_array_equal(w_of(hconv.convert_table(renamed, job=job)), w_of(hconv.convert_table(upper)))
    with pytest.raises(InputError, match=r"ixx, iyy, izz, ixy, ixz, iyz \(URDF\)"):
        hconv.convert_table(table(**vec("H", H)))


def test_convert_table_refuses_what_is_not_a_table():
    with pytest.raises(UsageError, match="convert_table takes a pyarrow Table or RecordBatch, got dict"):
        hconv.convert_table({"Hx": [1.0]})
