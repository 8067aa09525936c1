"""A body's inertial as a model file gives it, handed from a format's reader to the checks of
:mod:`hconv.tools.models`, and the rotations that place it.

Conventions (stated once, here, for every format; hconv's own are in :mod:`hconv.kernels.inertia`;
each format's way of writing a rotation is at the top of its reader, :mod:`hconv.tools.urdf`,
:mod:`hconv.tools.sdf`, :mod:`hconv.tools.mjcf`):

* B is a body's own frame: the URDF or SDF link frame, the MJCF body frame. Every format gives a
  body's inertia about its centre of mass C, in an inertial frame I placed in B by a pose: C's
  position ``p_BC_B`` [m] and a rotation ``R_BI`` whose columns are I's axes in B
  (``v_B = R_BI·v_I``). The tensor in B is ``I_C_B = R_BI · I_C_I · R_BIᵀ`` [kg·m²].
* Products of inertia are tensor entries, ``Ixy = -∫xy dm``, in URDF (``ixy``), SDF (``<ixy>``)
  and MJCF (``fullinertia``'s fourth number), as in hconv, so they are taken as they stand.
* URDF ``rpy`` and SDF ``<pose>``'s roll, pitch, yaw turn about the fixed axes X, then Y, then Z:
  ``R = Rz(yaw)·Ry(pitch)·Rx(roll)`` (:func:`rpy`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hconv.kernels.frames import quaternion_matrix
from hconv.tools.modelxml import Node, error


@dataclass(slots=True)
class ReadBody:
    """A body as read: the inertial's numbers in its own frame, or why there are none."""

    name: str
    source: str
    m: float = math.nan
    p_BC_B: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    R_BI: np.ndarray = field(default_factory=lambda: np.eye(3))
    I_C_I: np.ndarray | None = None
    status: str | None = None  #: no_inertial or unresolved_frame, with ``notes`` saying why
    notes: list[str] = field(default_factory=list)


def tensor(ixx: float, iyy: float, izz: float, ixy: float, ixz: float, iyz: float) -> np.ndarray:
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=np.float64)


def rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw)·Ry(pitch)·Rx(roll)``: URDF's and SDF's fixed-axis X, Y, Z."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rotation(q: list[float] | np.ndarray) -> np.ndarray:
    """The rotation of a quaternion (w, x, y, z), normalised (hconv's kernel)."""
    R, _ = quaternion_matrix(np.asarray(q, dtype=np.float64)[:, None])
    return R[:, :, 0]


def unit_vector(v: list[float], node: Node, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    n = float(np.linalg.norm(a))
    if not n > 0:
        raise error(node, f"{what} has zero length", f"give a non-zero {what}")
    return a / n
