"""S4 telescope models in-process: equations, parameters, the integrator and its status.

Sources: closed forms (momentum envelope, first integrals, the rigid model as the flexible one
without coupling, linear interpolation, the pyramid and octahedron clusters and the pyramid's
singularity measure), central finite differences for the Jacobian, the
gyro-momentum magnitudes of the reorientation (models/README.md, S4 [choice] of the rotor axes).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from descent_fmus.models.controllers.program_table import evaluate_program, program_values
from descent_fmus.models.integrators import LEFT_DOMAIN, RUNNING
from descent_fmus.models.params import ParameterError
from descent_fmus.models.telescope import AttitudeIntegrator
from descent_fmus.models.telescope_cmg import (gimbal_vectors, octahedron_axes, pyramid_axes,
                                               sing_max)
from descent_fmus.models.telescope_dynamics import (INITIAL_STATE, T_DEFAULT, TARGET_LAM, TARGET_W,
                                                    TelescopeParams, envelope_radius, gyro_momentum,
                                                    make_rigid_rhs, required_gyro_momentum,
                                                    rigid_jacobian, singularity_measure)
from descent_fmus.models.telescope_flexible import (PanelParams, flexible_initial_state,
                                                    make_flexible_rhs)

P = TelescopeParams()


def test_gyro_momentum_magnitudes():
    # models/README.md (rotor axes a_j = g_j x e_y): |k(beta0)| ~ 263 N m s and the end state
    # needs ~ 260 N m s
    assert np.linalg.norm(gyro_momentum(INITIAL_STATE[7:13], P)) == pytest.approx(263, abs=1)
    kf = required_gyro_momentum(INITIAL_STATE, TARGET_LAM, TARGET_W, P)
    assert np.linalg.norm(kf) == pytest.approx(260, abs=1)
    # closed form: along any direction the envelope is below 6h and above 6h sqrt(1 - 1) = 0
    assert 0 < envelope_radius(kf, P) < 6 * P.h


FOUR_GYROS = TelescopeParams(inertia=(11000.0, 0.0, 0.0, 0.0, 20000.0, 0.0, 0.0, 0.0, 20000.0),
                             rotor_ref="z", gimbal_axes=octahedron_axes())


@pytest.mark.parametrize("p", [P, FOUR_GYROS], ids=["six-dodecahedron", "four-octahedron"])
def test_rigid_jacobian_matches_finite_differences(p):
    # oracle: central finite differences of the right-hand side
    f, jac = make_rigid_rhs(p), rigid_jacobian(p)
    n, nx = p.n_gyros, p.n_states
    rng = np.random.default_rng(1)
    x = np.array(INITIAL_STATE[:7] + (0.0,) * n) + 0.2 * rng.standard_normal(nx)
    u = 0.05 * rng.standard_normal(n)
    A, B = jac(x[None], u[None])
    assert A.shape == (1, nx, nx) and B.shape == (1, nx, n)
    eps = 1e-6
    An = np.array([(np.array(f(tuple(x + eps * e), tuple(u))) -
                    np.array(f(tuple(x - eps * e), tuple(u)))) / (2 * eps) for e in np.eye(nx)]).T
    Bn = np.array([(np.array(f(tuple(x), tuple(u + eps * e))) -
                    np.array(f(tuple(x), tuple(u - eps * e)))) / (2 * eps) for e in np.eye(n)]).T
    np.testing.assert_allclose(A[0], An, atol=1e-8)
    np.testing.assert_allclose(B[0], Bn, atol=1e-8)


def test_cluster_geometries():
    # closed form: a pyramid's gimbal axes make alpha with its height, azimuths 2 pi / n apart
    a = math.radians(20.0)
    g = np.array(pyramid_axes(6, a)).reshape(6, 3)
    np.testing.assert_allclose(g @ (0.0, 0.0, 1.0), math.cos(a), atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-15)
    az = np.degrees(np.arctan2(g[:, 1], g[:, 0])) % 360.0
    np.testing.assert_allclose(np.diff(az), 60.0, atol=1e-12)
    # octahedron: four unit face normals (+-1, +-1, 1)/sqrt(3), no two parallel
    o = np.array(octahedron_axes()).reshape(4, 3)
    np.testing.assert_allclose(np.abs(o) * math.sqrt(3.0), 1.0, atol=1e-15)
    cos = o @ o.T
    assert np.all(np.abs(cos[~np.eye(4, dtype=bool)]) < 1.0 - 1e-9)
    # closed form: tangential rotors (rotor_ref z) at beta = 0 give C C^T = h^2 diag(3 cos^2 a,
    # 3 cos^2 a, 6 sin^2 a) for six at 60 deg, det/h^6 = 54 cos^4 a sin^2 a, k = 0
    p = TelescopeParams(rotor_ref="z", gimbal_axes=tuple(g.ravel()))
    assert singularity_measure(np.zeros(6), p) == pytest.approx(
        54 * math.cos(a) ** 4 * math.sin(a) ** 2, rel=1e-12)
    np.testing.assert_allclose(gyro_momentum(np.zeros(6), p), 0.0, atol=1e-12)
    assert singularity_measure(np.zeros(6), p) < sing_max(6) == 8.0
    # the default cluster is the six-axis dodecahedron
    assert P.n_gyros == 6 and FOUR_GYROS.n_gyros == 4 and FOUR_GYROS.n_states == 11


def test_gimbal_axes_are_validated():
    with pytest.raises(ParameterError, match="3 entries per gyrodyne"):
        P.with_(gimbal_axes=(1.0, 0.0)).validate()
    with pytest.raises(ParameterError, match="gimbal axis 2"):
        P.with_(gimbal_axes=(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)).validate()
    with pytest.raises(ParameterError, match="rotor_ref"):
        P.with_(rotor_ref=(0.0, 0.0, 1.0), gimbal_axes=(0.0, 0.0, 2.0)).validate()


def test_flexible_model_without_coupling_is_the_rigid_model():
    # closed form: with D = 0 the flexible equations reduce to the rigid ones
    pp = PanelParams(coupling=(0.0,) * 12)
    ff, fr = make_flexible_rhs(P, pp), make_rigid_rhs(P)
    x = flexible_initial_state(INITIAL_STATE)
    u = (0.01, -0.02, 0.03, 0.0, 0.01, -0.01)
    np.testing.assert_allclose(ff(x, u)[:13], fr(x[:13], u), atol=1e-15)


def test_program_table_with_node_times():
    # closed form: nodes (0, 2, -1) at t = 0, 1, 4: slopes 2 and -1
    table = [[0.0] * 6, [2.0] * 6, [-1.0] * 6]
    times = [0.0, 1.0, 4.0]
    u, du = evaluate_program(table, 3, 4.0, 0.25, times)
    assert u[0] == pytest.approx(0.5) and du[0] == pytest.approx(2.0)
    u, du = evaluate_program(table, 3, 4.0, 1.0, times)          # at a node: the next slope
    assert u[0] == pytest.approx(2.0) and du[0] == pytest.approx(-1.0)
    u, du = evaluate_program(table, 3, 4.0, 2.5, times)
    assert u[0] == pytest.approx(0.5) and du[0] == pytest.approx(-1.0)
    u, du = evaluate_program(table, 3, 4.0, 5.0, times)          # after the last node: hold
    assert u[0] == -1.0 and du[0] == 0.0
    vals = program_values(4.0, [[1.0], [2.0], [3.0]], times=times)
    assert vals["grid"] == 1 and vals["t_node[3]"] == 4.0 and vals["table[2,6]"] == 0.0
    with pytest.raises(ValueError, match="increasing"):
        program_values(4.0, [[1.0], [2.0]], times=[1.0, 1.0])


def test_program_table_interpolates_linearly():
    # closed form: linear interpolation between the nodes (0, 1, 0) at t = 0, 1, 2
    table = [[0.0] * 6, [1.0] * 6, [0.0] * 6]
    u, du = evaluate_program(table, 3, 2.0, 0.5)
    assert u[0] == pytest.approx(0.5) and du[0] == pytest.approx(1.0)
    u, du = evaluate_program(table, 3, 2.0, 1.0)          # at a node: the next segment's slope
    assert u[0] == pytest.approx(1.0) and du[0] == pytest.approx(-1.0)
    u, du = evaluate_program(table, 3, 2.0, 2.5)          # after t_end: hold the last value
    assert u[0] == 0.0 and du[0] == 0.0


def test_parameters_are_validated_with_the_name_of_the_culprit():
    assert P.validate() is P
    with pytest.raises(ParameterError, match="parameter h must be > 0"):
        P.with_(h=-1.0).validate()
    with pytest.raises(ParameterError, match=r"inertia\[1\] must be finite"):
        P.with_(inertia=(math.nan,) + P.inertia[1:]).validate()
    with pytest.raises(ParameterError, match="symmetric"):
        P.with_(inertia=(25000.0, 50.0) + P.inertia[2:]).validate()
    with pytest.raises(ParameterError, match="rotor_ref"):
        P.with_(rotor_ref=(0.0, 0.0, 0.0)).validate()
    with pytest.raises(ParameterError, match="coupling too strong"):
        PanelParams(coupling=(200.0,) + (0.0,) * 11).validate(P)
    with pytest.raises(ParameterError, match="modal frequencies"):
        PanelParams(freq=(0.2, 0.6, 0.2, 0.0)).validate(P)


def test_rotor_reference_by_name_is_the_axis_vector():
    assert TelescopeParams(rotor_ref="z").rotor_ref == (0.0, 0.0, 1.0)
    assert TelescopeParams(rotor_ref="y") == P
    # closed form: b_j = g_j x a_j, with a_j normal to g_j and to e_y
    g, a, b = gimbal_vectors(P.rotor_ref)
    for gj, aj, bj in zip(g, a, b):
        assert abs(np.dot(aj, (0.0, 1.0, 0.0))) < 1e-15 and abs(np.dot(gj, aj)) < 1e-15
        np.testing.assert_allclose(bj, np.cross(gj, aj), atol=1e-15)


def test_integrator_runs_to_the_stop_time_without_a_terminal_condition():
    # status convention: the reorientation has no terminal condition -> RUNNING, t_end -1
    ig = AttitudeIntegrator(make_rigid_rhs(P), INITIAL_STATE)
    for k in range(1, 81):
        ig.advance(k * T_DEFAULT / 80, (0.0,) * 6, (0.0,) * 6)
    assert ig.status == RUNNING and ig.running and ig.t_end_output == -1.0
    assert ig.t == pytest.approx(T_DEFAULT)
    # closed form: with the gimbals locked the body keeps |lambda| = 1 (RK4 to 1e-12)
    assert math.sqrt(sum(v * v for v in ig.x[:4])) == pytest.approx(1.0, abs=1e-12)


def test_integrator_leaves_the_domain_when_it_diverges():
    ig = AttitudeIntegrator(make_rigid_rhs(P), INITIAL_STATE)
    ig.advance(0.5, (0.0,) * 6, (0.0,) * 6)
    x_ok = ig.x
    ig.advance(1.0, (1e300,) * 6, (0.0,) * 6)            # absurd gimbal rates: non-finite state
    assert ig.status == LEFT_DOMAIN and not ig.running
    assert ig.t_end == 0.5 and ig.t_end_output == 0.5      # the last finite state's time
    assert ig.x == x_ok                                    # frozen at the last finite state
    ig.advance(1.5, (0.0,) * 6, (0.0,) * 6)
    assert ig.x == x_ok and ig.t == 0.5
    ig.reset()
    assert ig.status == RUNNING and ig.x == tuple(INITIAL_STATE) and ig.t_end_output == -1.0
    with pytest.raises(ParameterError, match="dt"):
        AttitudeIntegrator(make_rigid_rhs(P), INITIAL_STATE, dt=0.0)
