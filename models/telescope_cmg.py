"""S4 -- the geometry of the control-moment gyro cluster and the attitude kinematics, on plain
floats (shared by the rigid model, :mod:`models.telescope_dynamics`, and the flexible one).

* the gimbal-axis clusters: the default six face normals of a regular dodecahedron
  (:data:`GIMBAL_AXES`), :func:`pyramid_axes` and :func:`octahedron_axes` (Voronov 2009,
  Example 3);
* :func:`gimbal_vectors` -- the unit gimbal axes ``g_j``, the rotor axes ``a_j =
  normalize(g_j x e_ref)`` at ``beta_j = 0`` and ``b_j = g_j x a_j``;
* :func:`gyro_sums` -- the rotor momentum ``k`` and its rate ``k-dot`` of the gyrodynes;
* :func:`quaternion_rate`, :func:`quat_to_matrix` -- the attitude kinematics.

The equations of motion that use them are in :mod:`models.telescope_dynamics`.

References
----------
S.A. Voronov, PhD thesis (2009), ch. 2, Example 1; ch. 3, Example 3.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["PHI", "GIMBAL_AXES", "AXES", "pyramid_axes", "octahedron_axes", "axes_of",
           "sing_max", "gimbal_vectors", "gyro_sums", "quaternion_rate", "quat_to_matrix",
           "cross", "normalize"]

PHI = (1.0 + math.sqrt(5.0)) / 2.0
#: Gimbal axes (unnormalised): six non-parallel face normals of a regular dodecahedron.
GIMBAL_AXES = ((0.0, 1.0, PHI), (0.0, 1.0, -PHI), (1.0, PHI, 0.0), (-1.0, PHI, 0.0),
               (PHI, 0.0, 1.0), (PHI, 0.0, -1.0))


def cross(a, b):
    """Cross product ``a x b`` of two 3-vectors, on plain floats."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    """The unit vector along the 3-vector ``a`` (nonzero), on plain floats."""
    n = math.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
    return (a[0] / n, a[1] / n, a[2] / n)


#: Body axes by name, for ``rotor_ref``.
AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def pyramid_axes(n: int, alpha: float, azimuth0: float = 0.0) -> tuple:
    """Gimbal axes of a pyramid cluster, flattened (3 entries per gyrodyne).

    Gyrodyne ``j`` (0-based) at azimuth ``psi_j = azimuth0 + 2 pi j / n`` about the pyramid's
    height ``e_z``; its gimbal axis makes the angle ``alpha`` [rad] with the height:
    ``g_j = (sin alpha cos psi_j, sin alpha sin psi_j, cos alpha)``.
    """
    out = []
    for j in range(n):
        psi = azimuth0 + 2.0 * math.pi * j / n
        out += [math.sin(alpha) * math.cos(psi), math.sin(alpha) * math.sin(psi), math.cos(alpha)]
    return tuple(out)


def octahedron_axes() -> tuple:
    """Four gimbal axes normal to four pairwise non-parallel faces of a regular octahedron,
    flattened: ``(+-1, +-1, 1)/sqrt(3)`` -- the classical four-gyrodyne pyramid, whose gimbal
    axes make ``acos(1/sqrt(3))`` = 54.74 deg with its height ``e_z``."""
    r = 1.0 / math.sqrt(3.0)
    return tuple(v * r for g in ((1, 1, 1), (-1, 1, 1), (-1, -1, 1), (1, -1, 1)) for v in g)


def axes_of(flat) -> list:
    """Flattened gimbal axes (3 entries per gyrodyne) as a list of 3-tuples of floats."""
    return [tuple(float(v) for v in flat[3 * j:3 * j + 3]) for j in range(len(flat) // 3)]


def sing_max(n: int) -> float:
    """Largest value of the singularity measure det(C C^T)/h^6 for n gyrodynes: (n/3)^3
    (trace C C^T = n h^2; 8 for six)."""
    return (n / 3.0) ** 3


def gimbal_vectors(rotor_ref="y", axes=GIMBAL_AXES):
    """Unit gimbal axes ``g_j`` and the rotor axes ``a_j`` (beta=0), ``b_j = g_j x a_j``.

    ``rotor_ref`` is the reference direction ``e_ref`` of ``a_j = normalize(g_j x e_ref)``: a
    body axis by name (``"y"``, the default [choice], models/README.md; ``"z"`` gives a harder
    variant) or a 3-vector in body axes.  ``axes``: the gimbal axes, as 3-vectors or flattened
    (default: the dodecahedron cluster).
    """
    e = AXES[rotor_ref] if isinstance(rotor_ref, str) else tuple(rotor_ref)
    if axes and not isinstance(axes[0], (tuple, list)):
        axes = axes_of(axes)
    g = [normalize(v) for v in axes]
    a = [normalize(cross(gj, e)) for gj in g]
    b = [cross(gj, aj) for gj, aj in zip(g, a)]
    return g, a, b



def gyro_sums(x, u, gy, cos=math.cos, sin=math.sin):
    """Rotor momentum k and its rate k-dot of the gyrodynes, on plain floats.

    ``x[7:13]`` are the gimbal angles beta_j [rad], ``u`` the gimbal rates [rad/s], ``gy`` the
    pairs (h a_j, h b_j) [N m s]: k = sum h (a_j cos b_j + b_j sin b_j),
    k-dot = sum h (-a_j sin b_j + b_j cos b_j) u_j.  Returns (k1, k2, k3, kd1, kd2, kd3).
    """
    k1 = k2 = k3 = d1 = d2 = d3 = 0.0
    j = 0
    for (a, b) in gy:
        bj = x[7 + j]
        c, s = cos(bj), sin(bj)
        k1 += a[0] * c + b[0] * s
        k2 += a[1] * c + b[1] * s
        k3 += a[2] * c + b[2] * s
        uj = u[j]
        d1 += (b[0] * c - a[0] * s) * uj
        d2 += (b[1] * c - a[1] * s) * uj
        d3 += (b[2] * c - a[2] * s) * uj
        j += 1
    return k1, k2, k3, d1, d2, d3


def quaternion_rate(l0, l1, l2, l3, w1, w2, w3):
    """d(lambda)/dt = 1/2 A(omega) lambda (Voronov 2009), on plain floats."""
    return (0.5 * (-w1 * l1 - w2 * l2 - w3 * l3),
            0.5 * (w1 * l0 + w3 * l2 - w2 * l3),
            0.5 * (w2 * l0 - w3 * l1 + w1 * l3),
            0.5 * (w3 * l0 + w2 * l1 - w1 * l2))


def quat_to_matrix(lam) -> np.ndarray:
    """Rotation matrix R (body -> inertial) of the quaternion ``lam`` (scalar first)."""
    q0, q1, q2, q3 = (float(v) for v in lam[:4])
    return np.array([
        [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
        [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
        [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3]])
