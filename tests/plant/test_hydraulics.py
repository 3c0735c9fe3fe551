"""Seed chapter 3 checks on the hydraulics functions and the single actuator (seed §3.3, app. A)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexsim.errors import InputError
from hexsim.plant import hydraulics
from hexsim.plant.model import load_model
from hexsim.plant.params import HydraulicParams
from hexsim.studies.metrics import run_smoothness

P = HydraulicParams()
# Appendix A, typed in from the seed (not from HydraulicParams): the analytic references. g = 9.81, the
# value of the seed's accelerometer calibration (§2.3.1; app. A rounds it to 9.8), one value in both models.
PS, A1, A2, M, G = 7.0e6, math.pi / 4 * 0.04**2, math.pi / 4 * (0.04**2 - 0.03**2), 40.0, 9.81


def test_initial_pressure_is_the_seeds_formula(actuator_smooth):
    # Seed §3.3: P1(0) = (P_s - P_t) A2/A1 + M g / A1 with P_t = 0.
    expected = PS * A2 / A1 + M * G / A1
    assert actuator_smooth.p1_initial[0] == pytest.approx(expected, rel=1e-9)
    assert hydraulics.equilibrium_pressure(M * G, P) == pytest.approx(expected, rel=1e-12)


def test_one_gravity_in_both_models_and_the_identifiers():
    from hexsim.measured import discovery, friction_id
    from hexsim.plant.model import gravity, load_model

    for name in ("actuator", "hexapod"):
        assert np.linalg.norm(load_model(name).opt.gravity) == pytest.approx(G, abs=1e-12)
    # the identifiers keep no constant of their own: they read the model's g
    assert not any(isinstance(v, float) and 9.7 < v < 9.9 for m in (discovery, friction_id) for v in vars(m).values())
    assert gravity() == gravity("hexapod") == pytest.approx(G)


def test_eigenfrequency_formula_is_109_hz():
    # Seed §3.3: f_e = sqrt(2 E A / (M L_s)) / 2 pi ≈ 109 Hz; eq. (3.7) at mid-stroke gives the same.
    assert hydraulics.eigenfrequency(M, P, stroke=0.2) == pytest.approx(109.0, abs=0.5)
    assert hydraulics.eigenfrequency(M, P, y=0.1) == pytest.approx(109.0, abs=1.0)
    model = load_model("actuator")
    assert model.body("load").mass[0] == M  # the MJCF carries the seed's M


def test_flow_areas_match_seed_equations():
    x = np.array([-1e-3, -5e-6, 0.0, 4e-6, 1e-4])
    a1, a2 = hydraulics.flow_areas(x, P.replace(flow_area="sharp"))
    w = math.pi * 0.01
    np.testing.assert_allclose(a1, [0, 0, 0, 0, w * (1e-4 - 5e-6)])  # eq. (3.3)
    np.testing.assert_allclose(a2, [w * (1e-3 - 5e-6), 0, 0, 0, 0])
    x = np.array([-8e-5, -5e-6, 0.0, 4e-6, 7e-5])  # the working range of eq. (3.11)
    a1, a2 = hydraulics.flow_areas(x, P)
    np.testing.assert_allclose(a1 + a2, 300 * x**2)  # eq. (3.11)
    assert np.all(a1[x < 0] == 0) and np.all(a2[x > 0] == 0)


def test_orifice_flow_and_its_derivative():
    x_v, p1 = np.array([7e-5, -7e-5]), np.array([3.0e6, 3.0e6])  # inside the smooth range of eq. (3.11)
    phi = hydraulics.valve_flow(x_v, p1, P)
    a = 300 * 7e-5**2
    expected = [0.61 * a * math.sqrt(2 * (PS - 3e6) / 860), -0.61 * a * math.sqrt(2 * 3e6 / 860)]
    np.testing.assert_allclose(phi, expected, rtol=2e-3)  # C_d = pi/(pi+2) = 0.6110 vs the seed's 0.61
    h = 10.0
    numeric = (hydraulics.valve_flow(x_v, p1 + h, P) - hydraulics.valve_flow(x_v, p1 - h, P)) / (2 * h)
    np.testing.assert_allclose(hydraulics.valve_flow_dp1(x_v, p1, P), numeric, rtol=1e-6)


def test_friction_is_published_stribeck_with_arctan():
    v = np.array([-0.1, -1e-3, 0.0, 1e-3, 0.1])
    f = hydraulics.friction_force(v, P)
    expected = [
        1800 * -0.1 + math.atan(100 * -0.1) * (60 + 30 * math.exp(-0.1 / 0.005)),
        1800 * -1e-3 + math.atan(100 * -1e-3) * (60 + 30 * math.exp(-1e-3 / 0.005)),
        0.0,
        2200 * 1e-3 + math.atan(100 * 1e-3) * (65 + 30 * math.exp(-1e-3 / 0.005)),
        2200 * 0.1 + math.atan(100 * 0.1) * (65 + 30 * math.exp(-0.1 / 0.005)),
    ]
    np.testing.assert_allclose(f, expected)
    # As published, arctan tends to pi/2: the Coulomb level at speed is pi/2 F_c0; normalised it is F_c0.
    fast = hydraulics.friction_force(np.array([10.0]), P)[0] - 2200 * 10
    assert fast == pytest.approx(math.atan(1000) * 65, rel=1e-9)
    normalised = hydraulics.friction_force(np.array([10.0]), P.replace(arctan_normalised=True))[0] - 2200 * 10
    assert normalised == pytest.approx(65, rel=1e-3)


def test_pressure_step_is_stable_at_full_valve_opening():
    # Explicit Euler diverges here (valve-chamber pole ~30 µs < dt); the linearly implicit step settles
    # at the pressure where the valve flow feeds the piston motion.
    p1 = np.array([3.4e6])
    for _ in range(200):
        p1 = hydraulics.step_pressure(p1, np.array([10.0]), np.array([0.1]), np.array([0.0]), 1e-4, P)
    assert PS * 0.99 < p1[0] <= PS * 1.0001


def test_params_validate_themselves():
    with pytest.raises(InputError, match="bulk_modulus"):
        HydraulicParams(bulk_modulus=-1.0)
    with pytest.raises(InputError, match="overlap"):
        HydraulicParams(overlap=2e-3)


def _transient_spectrum(result, t_rev):
    """Amplitude spectrum of the acceleration from 50 ms before to 150 ms after a reversal (detrended)."""
    sel = (result.t > t_rev - 0.05) & (result.t < t_rev + 0.15)
    t, a = result.t[sel], result.acc[sel, 2]
    a = a - np.polyval(np.polyfit(t, a, 3), t)
    n = 1 << 15
    return np.fft.rfftfreq(n, t[1] - t[0]), np.abs(np.fft.rfft(a * np.hanning(a.size), n))


def test_sharp_area_rings_at_the_hydraulic_eigenfrequency(actuator_sharp, actuator_smooth):
    # Seed §3.3, Fig. 3.6: with the sharp-edged area (3.3) every dead-band crossing kicks the oil spring,
    # which rings at f_e. Reversals happen at y ≈ 0.05 and 0.15 m, where eq. (3.7) gives 153 and 89 Hz
    # (109 Hz at mid-stroke). Tolerance 10 %: the window is 0.2 s (5 Hz bins) and friction damps.
    sm = run_smoothness(actuator_sharp)
    assert sm.reversal_times.size == 2
    for t_rev in sm.reversal_times:
        y = actuator_sharp.y[np.argmin(np.abs(actuator_sharp.t - t_rev)), 0]
        f_e = hydraulics.eigenfrequency(M, P, y=y)
        f, spec_sharp = _transient_spectrum(actuator_sharp, t_rev)
        above = f > 40
        assert f[above][np.argmax(spec_sharp[above])] == pytest.approx(f_e, rel=0.10)
        # Seed Fig. 3.9: with the smooth area (3.11) the eigenfrequency is not excited.
        _, spec_smooth = _transient_spectrum(actuator_smooth, t_rev)
        band = np.abs(f - f_e) < 0.15 * f_e
        assert spec_smooth[band].max() < spec_sharp[band].max() / 10


def test_smooth_area_gives_two_peaks_at_every_reversal(actuator_smooth):
    # Seed Fig. 3.9: "two peaks can be recognized each time the valve spool passes x_v = 0".
    sm = run_smoothness(actuator_smooth)
    assert sm.reversal_times.size == 2
    for t_rev in sm.reversal_times:
        win = np.abs(sm.t - t_rev) <= 0.1
        noise = sm.noise[win]
        assert noise.max() > 4 * sm.noise_floor
        assert noise.min() < -4 * sm.noise_floor
        # one peak of each sign, the second following the first within 0.1 s (about 60 ms here)
        t_max, t_min = sm.t[win][np.argmax(noise)], sm.t[win][np.argmin(noise)]
        assert abs(t_max - t_min) < 0.1


def test_flow_curve_has_a_flat_zone_around_zero(actuator_smooth):
    # Seed Fig. 3.5/3.10: velocity vs valve setpoint is flat near u_v = 0 (dead band of the overlap).
    r = actuator_smooth
    sel = r.t > 2.0
    u, v = r.u_v[sel, 0], r.ydot[sel, 0]

    def slope(lo, hi):
        m = (np.abs(u) > lo) & (np.abs(u) < hi)
        return np.polyfit(u[m], v[m], 1)[0] if np.all(u[m] > 0) or np.all(u[m] < 0) else np.polyfit(np.abs(u[m]), np.abs(v[m]), 1)[0]

    assert slope(0.0, 0.08) < 0.2 * slope(0.5, 0.9)
    assert np.all(np.sign(v[np.abs(u) > 0.3]) == np.sign(u[np.abs(u) > 0.3]))


def test_smooth_flow_area_never_exceeds_the_ports_opening():
    # Seed eq. (3.11) near the null, the sharp-edged port of eq. (3.3) at large openings, C^1 in between.
    d, k, o = 0.01, 300.0, 5e-6  # app. A, typed in
    x = np.linspace(-1.1e-3, 1.1e-3, 400_001)
    a1, a2 = hydraulics.flow_areas(x, P)
    area = a1 + a2
    port = math.pi * d * (np.abs(x) - o)
    far = np.abs(x) >= 2 * o  # near the null the smooth curve stands for the clearance flow of the overlap
    assert np.all(area[far] <= port[far] * (1 + 1e-12))
    assert area[-1] == pytest.approx(port[-1], rel=1e-12)  # full stroke: the port, not 10.5x it
    near = np.abs(x) <= 8e-5  # the working range the seed matched (3.11) to is unchanged
    np.testing.assert_allclose(area[near], k * x[near] ** 2, rtol=1e-15)
    slope = np.diff(area) / np.diff(x)  # C^1: no jump in the slope anywhere
    assert np.max(np.abs(np.diff(slope))) < 2 * k * (x[1] - x[0]) * 1.01
    phi = hydraulics.valve_flow(1.1e-3, 0.0, P)  # full opening against 70 bar: the port's flow, C_d = pi/(pi+2)
    assert phi == pytest.approx(math.pi / (math.pi + 2) * math.pi * d * (1.1e-3 - o) * math.sqrt(2 * 7e6 / 860), rel=1e-5)


def test_a_rounded_edge_opens_from_null_and_meets_the_port_with_a_kink():
    """Flow area "rounded": k_a x_v^2 (3.11) from null, no dead band, until it meets the port's pi d (x_v - O_l)
    (3.3) from below, the port beyond (the shape of the reference plant R1's spool: the flow gain halves at the
    corner). Checked against the formulas typed in: the corner is the larger root of k_a x^2 = pi d (x - O_l),
    0.89 V with R1's published values (k_a 280, d 9.5 mm, O_l 8 µm); the opening is continuous there, its slope
    drops from 2 k_a x_c to pi d; the edge passes flow at any opening (no dead band) and the other edge nothing."""
    d, k, o = 0.0095, 280.0, 8e-6
    hyd = HydraulicParams(flow_area="rounded", spool_diameter=d, smooth_area_gain=k, overlap=o)
    w = math.pi * d
    corner = (w + math.sqrt(w * w - 4 * k * w * o)) / (2 * k)
    assert hyd.rounded_corner == pytest.approx(corner, rel=1e-12)
    assert corner / hyd.x_v_max * hyd.u_v_max == pytest.approx(0.89, abs=0.001)
    x = np.linspace(-1.1e-3, 1.1e-3, 220_001)
    a1, a2 = hydraulics.flow_areas(x, hyd)
    expected = np.where(np.abs(x) <= corner, k * x**2, w * (np.abs(x) - o))
    np.testing.assert_allclose(a1 + a2, expected, rtol=1e-13, atol=1e-20)
    assert np.all(a1[x > 0] > 0) and np.all(a1[x <= 0] == 0) and np.all(a2[x >= 0] == 0)
    assert k * corner**2 == pytest.approx(w * (corner - o), rel=1e-12)  # continuous at the corner
    assert 2 * k * corner / w == pytest.approx(2.0, rel=0.2)  # the flow gain about halves there
    with pytest.raises(InputError, match="never meets the port"):
        HydraulicParams(flow_area="rounded", spool_diameter=d, smooth_area_gain=k, overlap=w / (4 * k) * 1.01)


def test_cavitation_floor_keeps_the_oil_volume():
    # A closed valve (x_v = 0: no opening) and the piston pulled out 10 mm and pushed back: the oil cannot
    # stretch below the cavitation pressure, a cavity opens instead, and it closes again on the way back,
    # so the chamber returns to its start pressure (continuity: the same oil in the same volume).
    from hexsim.plant.effects import Effects
    from hexsim.plant.legs import PlantState, step_plant

    state, y, dt = PlantState.at_rest([4.0e6], [0.0], P), 0.1, 1e-4
    lowest = []
    for v in (0.05, -0.05):
        for _ in range(2000):
            state, _ = step_plant(state, 0.0, [y], [v], dt, P, Effects())
            y += v * dt
        lowest.append(state.p1[0])
    assert lowest[0] == P.cavitation_pressure == pytest.approx(0.1e5 - 101325.0)  # 0.1 bar absolute
    assert state.v_c[0] == 0.0 and state.p1[0] == pytest.approx(4.0e6, rel=1e-3)


def test_opening_table_interpolates_from_the_origin_on_both_sides_of_null():
    """flow_area "table": the opening is pi d x_v,max times the table's fraction at |u_v|, linear between
    points from (0, 0) (written out here), the same on the side x_v < 0."""
    p = HydraulicParams(flow_area="table", opening_table=((1.0, 0.0), (3.0, 0.25), (10.0, 1.0)))
    full = math.pi * p.spool_diameter * p.x_v_max
    for u, fraction in ((0.5, 0.0), (1.0, 0.0), (2.0, 0.125), (3.0, 0.25), (6.5, 0.625), (10.0, 1.0)):
        x = u / p.u_v_max * p.x_v_max
        a1, a2 = hydraulics.flow_areas(x, p)
        assert (a1, a2) == pytest.approx((full * fraction, 0.0), abs=1e-15)
        a1, a2 = hydraulics.flow_areas(-x, p)
        assert (a1, a2) == pytest.approx((0.0, full * fraction), abs=1e-15)
    with pytest.raises(InputError, match="must end at u_v_max"):
        HydraulicParams(flow_area="table", opening_table=((1.0, 0.1), (5.0, 0.5)))


def test_an_opening_table_that_starts_below_null_opens_both_edges_around_it():
    """An underlapped valve as a table: each edge opens 0.5 V before null, so at null both are open (half the
    first point's opening, written out here), A→T closes at +0.5 V, P→A at -0.5 V; a point below null must
    have opening 0."""
    p = HydraulicParams(flow_area="table", opening_table=((-0.5, 0.0), (0.5, 0.02), (10.0, 1.0)))
    full = math.pi * p.spool_diameter * p.x_v_max
    at_06 = 0.02 + 0.1 * (1.0 - 0.02) / 9.5  # A→T at +0.6 V: 0.1 V along the line from (0.5, 0.02) to (10, 1)
    for u, (f1, f2) in ((0.0, (0.01, 0.01)), (0.25, (0.015, 0.005)), (0.5, (0.02, 0.0)), (-0.6, (0.0, at_06))):
        a1, a2 = hydraulics.flow_areas(u / p.u_v_max * p.x_v_max, p)
        assert (a1, a2) == pytest.approx((full * f1, full * f2), abs=1e-15), u
    with pytest.raises(InputError, match="opening 0"):
        HydraulicParams(flow_area="table", opening_table=((-0.5, 0.01), (10.0, 1.0)))
    with pytest.raises(InputError, match="set flow_area to 'table'"):
        HydraulicParams(opening_table=((10.0, 1.0),))
