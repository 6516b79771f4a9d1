"""Mixed strain / stress control through the auxiliary nodes: the servo of
loading.mixed.StressControl on the simple cubic cell in the elastic range."""

from dataclasses import replace

import numpy as np
import pytest
from mpfem_fenicsx.meshes.packing import Packing, simple_cubic_packing
from mpi4py import MPI

from mpfem_fenicsx.loading.mixed import StressControl
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.workflows.compaction import CompactionCase, run_compaction
from test_granular import quiet, small_case


def test_control_integrates_the_velocity_gradient():
    """Strain-driven components follow F0(t) = exp(L t) exactly; the servo's components move
    against the stress error, saturating at ``rate``; time only advances."""
    L = np.diag([0.0, 0.0, -20.0])
    control = StressControl(
        duration=1e-3,
        stress_driven=np.diag([True, True, False]),
        target=lambda t: np.eye(3),
        rate=50.0,
        band=0.5,
        velocity_gradient=lambda t: L,
    )
    times = np.linspace(0.0, 1e-3, 11)
    F = [control(t) for t in times]
    assert F[-1][2, 2] == pytest.approx(np.exp(-20.0 * 1e-3), rel=1e-12)
    assert F[-1][0, 0] == 1.0  # servo idle: no stress measured yet
    assert np.array_equal(control(times[-2]), F[-2])  # the step before is remembered
    # sigma_11 below its target of 1 MPa, sigma_22 above
    control.update(1e-3, np.diag([0.0, 2.0, 0.0]))
    F2 = control(2e-3)
    # compressed at the full rate
    assert F2[0, 0] / F[-1][0, 0] == pytest.approx(np.exp(-50.0 * 1e-3))
    # expanded (error -1 MPa: saturated)
    assert F2[1, 1] / F[-1][1, 1] == pytest.approx(np.exp(50.0 * 1e-3))
    with pytest.raises(ValueError, match="time must advance"):
        control(0.5e-3)
    with pytest.raises(ValueError, match="stress_driven must be a symmetric"):
        StressControl(
            duration=1.0,
            stress_driven=np.triu(np.ones((3, 3), bool)),
            target=lambda t: 0,
            rate=1,
            band=1,
        )
    with pytest.raises(ValueError, match="control .* needs boundary.condition CLP or CLPS"):
        CompactionCase.build(condition="GDF", control=control)


def test_lode_shear_keeps_the_mean_stress():
    """The Lode-angle probe's targets: constant mean stress, von Mises equivalent q ramped, the
    principal order of triaxial compression at 0 and of triaxial extension at 60 degrees."""
    from mpfem_fenicsx.homogenization import stress_invariants
    from mpfem_fenicsx.loading.mixed import lode_shear_control

    for theta in np.radians([0.0, 20.0, 60.0, 137.0]):
        control = lode_shear_control(
            mean=3.0, q_max=2.0, theta=theta, duration=1e-3, rate=10.0, band=1.0, t0=5e-4
        )
        sigma = control.target(1e-3)  # half-way
        # the invariants' convention: tension > 0 in, compression > 0 out
        m, q = stress_invariants(-sigma)
        assert m == pytest.approx(3.0) and q == pytest.approx(1.0)
        assert stress_invariants(-control.target(2e-3))[1] == pytest.approx(2.0)  # held at q_max
        assert stress_invariants(-control.target(4e-4))[1] == pytest.approx(0.0)  # before t0
    s0 = np.diag(lode_shear_control(1.0, 1.0, 0.0, 1.0, 1.0, 1.0).target(1.0))
    s60 = np.diag(lode_shear_control(1.0, 1.0, np.pi / 3, 1.0, 1.0, 1.0).target(1.0))
    assert s0[0] > s0[1] and s0[1] == pytest.approx(s0[2])
    assert s60[0] == pytest.approx(s60[1]) and s60[1] > s60[2]


def servo_on_a_linear_plant(
    K, drift, integral_time, filter_time=0.0, noise=0.0, T=0.02, dt=1e-5, ramp=0.0
):
    """Error history (MPa) of a servo holding sigma_11 at 1 MPa (+ ``ramp`` t) on a model medium
    whose stress is sigma_11 = K (-ln F11) + drift t (+ white noise of amplitude ``noise`` in the
    measure)."""
    rng = np.random.default_rng(0)
    control = StressControl(
        duration=T,
        stress_driven=np.diag([True, False, False]),
        rate=50.0,
        band=0.5,
        target=lambda t: (1.0 + ramp * t) * np.eye(3),
        integral_time=integral_time,
        filter_time=filter_time,
    )
    errors = []
    for t in np.arange(0.0, T, dt):
        sigma = K * -np.log(control(t)[0, 0]) + drift * t
        control.update(t, np.diag([sigma + noise * rng.standard_normal(), 0.0, 0.0]))
        errors.append(1.0 + ramp * t - sigma)
    return np.array(errors)


def test_pi_servo_follows_a_drifting_stress():
    """An independent model of the plant: with a stress drifting at D = 200 MPa/s (what the axial
    compression does to the lateral stress of a triaxial test), the proportional servo lags by
    the analytic D band / (K rate) = 0.05 MPa; the PI servo (integral time 4 band / (K rate))
    brings the error below 1e-3 MPa; through a filtered noisy measure (0.1 MPa) it follows the
    noise but does not lag; a target ramped at R MPa/s is followed through a filter of time tau
    without the lag R tau of the filtered measure."""
    K, D = 40.0, 200.0  # MPa, MPa/s
    lag = D * 0.5 / (K * 50.0)
    p_only = servo_on_a_linear_plant(K, D, integral_time=None)
    assert p_only[-1] == pytest.approx(-lag, rel=1e-2)
    tau = 0.5 / (K * 50.0)
    pi = servo_on_a_linear_plant(K, D, integral_time=4 * tau)
    assert abs(pi[-1]) < 1e-3 and np.abs(pi[len(pi) // 2 :]).max() < 1e-3
    noisy = servo_on_a_linear_plant(K, D, integral_time=4 * tau, filter_time=0.5 * tau, noise=0.1)
    assert np.abs(noisy[len(noisy) // 2 :]).mean() < 0.5 * lag  # noise followed, no lag
    # a ramped target (100 MPa/s): an average lags the stress it follows by ramp x filter_time,
    # which the PI servo would hold as an overshoot; the filter's own rate makes that up
    filtered = servo_on_a_linear_plant(K, D, integral_time=4 * tau, filter_time=tau, ramp=100.0)
    assert np.abs(filtered[len(filtered) // 2 :]).max() < 0.05 * 100.0 * tau
    with pytest.raises(ValueError, match="integral_time must be > 0"):
        StressControl(
            duration=1.0,
            stress_driven=np.eye(3, dtype=bool),
            target=lambda t: 0,
            rate=1,
            band=1,
            integral_time=0.0,
        )


def test_pi_servo_does_not_overshoot_the_end_of_a_ramp():
    """An elastoplastic model medium (elastic modulus 4000 MPa, linear hardening 100 MPa) ramped
    to 2 MPa at 2000 MPa/s, then held: the PI servo's integral holds the strain rate that followed
    the ramp; unwinding it after the knot drove the stress 0.064 MPa (3 %) past the target. The
    integral is scaled with the target's rate: the stress settles within 1 % of the target."""
    E, H, R, t_ramp = 4000.0, 100.0, 2000.0, 1e-3
    target = lambda t: min(R * t, R * t_ramp) * np.eye(3)  # noqa: E731
    control = StressControl(
        duration=2e-3,
        stress_driven=np.diag([True, False, False]),
        rate=100.0,
        band=0.5,
        target=target,
        integral_time=1e-4,
        filter_time=1e-5,
    )
    plastic, errors, times = 0.0, [], np.arange(0.0, 2e-3, 2e-7)
    for t in times:
        strain = -np.log(control(t)[0, 0])
        sigma = E * (strain - plastic)
        if sigma > H * plastic:  # plastic loading: return to the hardening line
            plastic = E * strain / (E + H)
            sigma = H * plastic
        control.update(t, np.diag([sigma, 0.0, 0.0]))
        errors.append(sigma - target(t)[0, 0])
    errors = np.array(errors)
    held = errors[times > t_ramp]
    assert np.abs(held).max() < 0.01 * 2.0
    assert abs(held[-1]) < 1e-6


def test_consolidation_then_triaxial_on_the_simple_cubic_cell(tmp_path):
    """Consolidation under stress control and a CI-sized triaxial path: the 8 touching spheres of
    the simple cubic cell (elastic: sigma_0 = 10 GPa). Isotropic consolidation, the three normal
    stresses servo-controlled on the Schmidt stress to p0 = 2 MPa (ramp, then hold to rest): at the
    end of the hold the Schmidt stress meets p0 within 1 %, and so does the volume average of the
    particles' Cauchy stress (eq. C.7, over the hold's last rows: the elastic particles ring about
    equilibrium), a measure the servo never sees. Then axial compression (F33 strain-driven) at
    constant lateral stress: sigma11, sigma22 stay within 2 % of p0 while sigma33 rises."""
    p0, T = 2.0, 2e-3
    consolidation = 0.5 * T

    def mask(t):
        return np.eye(3, dtype=bool) if t < consolidation else np.diag([True, True, False])

    control = StressControl(
        duration=T,
        stress_driven=mask,
        rate=50.0,
        band=0.5,
        target=lambda t: p0 * min(t / (0.3 * T), 1.0) * np.eye(3),
        velocity_gradient=lambda t: (
            np.diag([0.0, 0.0, -10.0]) if t >= consolidation else np.zeros((3, 3))
        ),
    )
    case = small_case(
        tmp_path,
        condition="CLP",
        control=control,
        material=replace(LEAD, sigma_0=1e4),
        duration=T,
        increments=2000,
        outputs=40,
    )
    h = run_compaction(case, MPI.COMM_SELF, log=quiet).history
    t = h.column("time")
    held = np.flatnonzero((t > 0.4 * T) & (t <= consolidation + 1e-12))
    axial = np.flatnonzero(t > consolidation + 0.05 * T)
    assert held.size >= 3 and h.column("F33")[held[-1]] < 0.995  # the servo compacted the cell
    for i in (1, 2, 3):
        assert h.column(f"sigma_schmidt_{i}{i}")[held[-1]] == pytest.approx(p0, rel=0.01)
        assert np.mean(h.column(f"sigma_vol_{i}{i}")[held[-4:]]) == pytest.approx(p0, rel=0.01)
    for i in (1, 2):
        assert np.abs(h.column(f"sigma_schmidt_{i}{i}")[axial] / p0 - 1).max() < 0.02
    assert h.column("sigma_schmidt_33")[-1] > 1.5 * p0
    assert abs(h.column("sigma_schmidt_12")[-1]) < 1e-3 * p0


def test_servo_reads_the_reported_volume_stress(tmp_path):
    """With ``measure="volume"`` the stress the servo reads is the ``sigma_vol_*`` columns' (eq. C.7
    over V0 det F, F the centroids' least-squares gradient, the density's volume): at every output
    (servo update and row on the same state) the two agree to round-off. One sphere of the simple
    cubic cell is moved 1 % of its radius along x: its contacts close one side first, the
    centroids leave the affine motion and det F departs from the cell's det F0 (rho from
    rho_imposed), so a stress over V0 det F0 would not agree."""
    cubic = simple_cubic_packing()
    centres = np.array(cubic.centres)
    centres[0, 0] += 0.01 * cubic.radii[0]
    packing = Packing(cell=cubic.cell, centres=centres, radii=cubic.radii)
    control = StressControl(
        duration=4e-4,
        stress_driven=np.eye(3, dtype=bool),
        rate=50.0,
        band=0.5,
        target=lambda t: 2.0 * min(t / 2e-4, 1.0) * np.eye(3),
        measure="volume",
    )
    seen = {}
    servo_update = control.update

    def recording_update(t, sigma):
        seen[t] = np.array(sigma)
        servo_update(t, sigma)

    control.update = recording_update
    case = small_case(
        tmp_path,
        condition="CLP",
        control=control,
        spheres=packing,
        duration=4e-4,
        material=replace(LEAD, sigma_0=1e4),
        increments=400,
        outputs=4,
    )
    h = run_compaction(case, MPI.COMM_SELF, log=quiet).history
    assert h.column("sigma_vol_11")[-1] > 1.0  # the servo compressed the cell
    assert np.abs(h.column("rho") / h.column("rho_imposed") - 1).max() > 1e-4  # det F != det F0
    for k, t in enumerate(h.column("time")):
        reported = np.array(
            [[h.column(f"sigma_vol_{i}{j}")[k] for j in (1, 2, 3)] for i in (1, 2, 3)]
        )
        np.testing.assert_allclose(seen[t], reported, rtol=1e-12, atol=1e-12 * abs(reported).max())


def test_strain_path_replayed_under_stress_control(tmp_path):
    """A die compaction (strain-driven, elastic simple cubic cell, then
    held at rest), then the same cell driven by the three normal Schmidt stresses that compaction
    produced (PI servo). Along the path the replay passes through the strain-driven states (its
    strains at the stress it reached are the strain-driven ones at that stress), and at rest at
    the end its strains are the strain-driven ones, within 2 % of the axial strain."""
    T = 1e-3
    material = replace(LEAD, sigma_0=1e4)
    strain = run_compaction(
        small_case(
            tmp_path / "strain",
            condition="CLP",
            path="die",
            target_density=0.53,
            material=material,
            duration=T,
            increments=1000,
            outputs=20,
            hold=0.5,
        ),
        MPI.COMM_SELF,
        log=quiet,
    ).history
    t = np.concatenate([[0.0], strain.column("time")])
    recorded = np.vstack(
        [np.zeros(3), np.column_stack([strain.column(f"sigma_schmidt_{i}{i}") for i in (1, 2, 3)])]
    )

    def target(s):
        return np.diag([np.interp(s, t, recorded[:, i]) for i in range(3)])

    peak = recorded[:, 2].max()
    control = StressControl(
        duration=t[-1],
        stress_driven=np.eye(3, dtype=bool),
        target=target,
        rate=100.0,
        band=0.1 * peak,
        integral_time=2e-4,
    )
    replay = run_compaction(
        small_case(
            tmp_path / "replay",
            condition="CLP",
            control=control,
            material=material,
            duration=T,
            increments=1000,
            outputs=20,
        ),
        MPI.COMM_SELF,
        log=quiet,
    ).history
    h_strain = [np.log(strain.column(f"F{i}{i}")) for i in (1, 2, 3)]
    h_replay = [np.log(replay.column(f"F{i}{i}")) for i in (1, 2, 3)]
    scale = abs(h_strain[2][-1])
    assert scale > 0.02 and peak > 0
    for i in range(3):  # at rest at the end
        assert abs(h_replay[i][-1] - h_strain[i][-1]) < 0.02 * scale, i
    # along the loading: the strain-driven states at the stress the replay measured
    loading = strain.column("time") <= T
    sigma = replay.column("sigma_schmidt_33")
    on_path = (replay.column("time") <= T) & (sigma > 0.2 * peak) & (sigma < 0.95 * peak)
    assert on_path.sum() >= 5
    expected = np.interp(
        sigma[on_path], strain.column("sigma_schmidt_33")[loading], h_strain[2][loading]
    )
    assert np.abs(h_replay[2][on_path] - expected).max() < 0.02 * scale


def test_stress_controlled_run_restarts_bit_for_bit(tmp_path):
    """The servo's state (integrated F0, velocity gradient, filter, integral) is checkpointed: a
    stress-controlled run restarted from its mid-run checkpoint gives the uninterrupted history."""
    from mpfem_fenicsx.io.checkpoint import CheckpointError

    def case(out):
        control = StressControl(
            duration=4e-4,
            stress_driven=np.eye(3, dtype=bool),
            rate=50.0,
            band=0.5,
            target=lambda t: 2.0 * min(t / 2e-4, 1.0) * np.eye(3),
            integral_time=1e-4,
            filter_time=5e-6,
        )
        return small_case(
            out,
            condition="CLP",
            control=control,
            material=replace(LEAD, sigma_0=1e4),
            duration=4e-4,
            increments=400,
            outputs=4,
            checkpoint_every=2,
        )

    a = run_compaction(case(tmp_path / "a"), MPI.COMM_SELF, log=quiet).history
    restarted = run_compaction(
        case(tmp_path / "b"),
        MPI.COMM_SELF,
        log=quiet,
        restart=tmp_path / "a" / "checkpoints" / "step0000200",
    )
    b = restarted.history
    # the restarted run's wall time goes on from the killed run's (history rows and result)
    import json

    before = json.loads((tmp_path / "a" / "checkpoints" / "step0000200" / "meta.json").read_text())[
        "wall_time"
    ]
    assert restarted.wall_time >= b.column("wall_time")[-1] > before
    assert a.column("sigma_schmidt_11")[-1] > 0.5  # the servo compressed the cell
    for name in ("F11", "F33", "sigma_schmidt_11", "sigma_vol_22", "rho"):
        np.testing.assert_array_equal(a.column(name), b.column(name), err_msg=name)
    # a stress path continuing a strain-driven compaction from its checkpoint: it starts at the
    # checkpoint's gradient, and the pressure it holds is met
    strain_driven = small_case(
        tmp_path / "c",
        condition="CLP",
        material=replace(LEAD, sigma_0=1e4),
        target_density=0.52,
        duration=4e-4,
        increments=400,
        outputs=2,
        checkpoint_every=1,
    )
    c = run_compaction(strain_driven, MPI.COMM_SELF, log=quiet).history
    held = StressControl(
        duration=8e-4,
        stress_driven=np.eye(3, dtype=bool),
        rate=50.0,
        band=0.5,
        target=lambda t: c.column("sigma_schmidt_11")[-1] * np.eye(3),
        integral_time=1e-4,
    )
    d = run_compaction(
        small_case(
            tmp_path / "d",
            condition="CLP",
            control=held,
            material=replace(LEAD, sigma_0=1e4),
            duration=4e-4,
            increments=400,
            outputs=4,
        ),
        MPI.COMM_SELF,
        log=quiet,
        restart=tmp_path / "c" / "checkpoints" / "step0000400",
    ).history
    new = d.column("time") > 4e-4 * (1 + 1e-9)  # the rows after the restart (the history goes on)
    assert new.sum() == 2 and np.array_equal(d.column("F33")[~new], c.column("F33"))
    strain = abs(c.column("F33")[-1] - 1)
    assert strain > 1e-3 and np.abs(d.column("F33")[new] - c.column("F33")[-1]).max() < 0.1 * strain
    with pytest.raises(CheckpointError, match="does not record its gradient"):
        import json

        meta = tmp_path / "c" / "checkpoints" / "step0000400" / "meta.json"
        data = json.loads(meta.read_text())
        data.pop("F0")
        meta.write_text(json.dumps(data))
        run_compaction(case(tmp_path / "e"), MPI.COMM_SELF, log=quiet, restart=meta.parent)


def test_deviatoric_fan_analysis(tmp_path):
    """The Lode angle of a stress state is the angle its targets were built with; the yield point
    of a probe is where E_d first passes E_0 (1 + threshold); the figure is drawn; bad cases are
    refused before any computation."""
    from mpfem_fenicsx.loading.mixed import lode_direction
    from mpfem_fenicsx.workflows.deviatoric_surface import (
        DeviatoricSurfaceCase,
        lode_angle,
        write_outputs,
        yield_point,
    )

    for theta in (0.0, 17.0, 60.0, 200.0):
        assert lode_angle(3.0 + 1.7 * lode_direction(np.radians(theta))) == pytest.approx(
            theta % 360, abs=1e-9
        )
    rows = {
        "sigma_m": np.full(5, 1.0),
        "q": np.array([0.0, 0.5, 1.0, 1.5, 2.0]),
        "lode_deg": np.full(5, 30.0),
        "E_d": np.array([1.0, 1.0, 1.001, 1.005, 1.02]),
        "time": np.arange(5.0),
        "theta_deg": np.full(5, 30.0),
    }
    m, q, lode = yield_point(rows, E_0=1.0, threshold=3e-3)
    assert q == pytest.approx(1.0 + 0.5 * (0.003 - 0.001) / 0.004) and m == 1.0 and lode == 30.0
    assert yield_point(rows, E_0=1.0, threshold=0.5) is None
    case = DeviatoricSurfaceCase(out_dir=str(tmp_path))
    write_outputs(tmp_path, [rows], [(30.0, m, q, lode), (0.0, 1.0, 1.4, 0.0)], case)
    assert (tmp_path / "deviatoric_surface.png").stat().st_size > 1000
    assert (tmp_path / "surface.csv").read_text().count("\n") == 3
    with pytest.raises(ValueError, match="p_probe must be in"):
        DeviatoricSurfaceCase(p_load=1.0, p_probe=1.5)
    with pytest.raises(ValueError, match="bc CLP or CLPS"):
        DeviatoricSurfaceCase(base=CompactionCase.build(condition="GDF"))


@pytest.mark.heavy
def test_deviatoric_fan_on_the_simple_cubic_cell(tmp_path):
    """The Lode-angle fan on the 8 touching lead spheres of the simple cubic cell, loaded to
    p_load = 2 MPa and unloaded to p = 1.6 MPa. The cell's contacts lie along the axes: were each
    axis' contacts loaded by its principal stress alone, they would flatten again once it passes
    the largest value they carried, and the surface would be the triangle
    sigma_max = p + (2/3) q cos(theta) = c >= p_load, q_y = 1.5 (c - p) / cos(theta) (a von Mises
    circle would have q_y constant). Measured (2026-11-25; iso-dissipation 0.3 %): the probes at 0,
    20 and 40 deg yield at q = 1.69, 1.76, 1.99 MPa, sigma_max = 2.72, 2.70, 2.61 MPa: past p_load,
    q rising with theta, between the circle and the triangle (the spheres couple the axes: the
    x contacts' flattening spreads the particle sideways). Checked: every probe yields, at the mean
    stress held within 5 % and along its Lode angle within 5 deg, sigma_max > p_load and within
    10 % across the probes, q_y increasing with theta."""
    from mpfem_fenicsx.workflows.deviatoric_surface import (
        DeviatoricSurfaceCase,
        run_deviatoric_surface,
    )

    base = small_case(tmp_path, condition="CLP", duration=1e-3, increments=1000, outputs=10)
    case = DeviatoricSurfaceCase(
        base=base,
        p_load=2.0,
        p_probe=1.6,
        q_max=2.2,
        angles_deg=(0.0, 20.0, 40.0),
        rows_per_probe=40,
        out_dir=str(tmp_path / "fan"),
    )
    result = run_deviatoric_surface(case, MPI.COMM_SELF, log=quiet)
    assert len(result["points"]) == 3
    sigma_max = []
    for theta, sigma_m, q, lode in result["points"]:
        assert sigma_m == pytest.approx(1.6, rel=0.05)
        assert lode == pytest.approx(theta, abs=5.0)
        sigma_max.append(sigma_m + 2.0 / 3.0 * q * np.cos(np.radians(lode)))
    assert min(sigma_max) > 2.0 and max(sigma_max) < 1.10 * min(sigma_max), sigma_max
    q = [point[2] for point in result["points"]]
    assert q[0] < q[1] < q[2], q
    assert (tmp_path / "fan" / "deviatoric_surface.png").exists()


def test_stress_path_waypoints():
    """Load / unload / reload under stress control: the normal stresses follow the waypoints
    linearly and are held after the last; pressure_control is such a path; bad waypoints refused."""
    from mpfem_fenicsx.loading.mixed import normal_stress_path, pressure_control

    path = normal_stress_path(
        [0.0, 1.0, 2.0, 3.0], [[0, 0, 0], [2, 2, 2], [0.5, 0.5, 0.5], [3, 3, 4]], rate=1.0, band=1.0
    )
    assert np.allclose(np.diag(path.target(0.5)), 1.0) and np.allclose(
        np.diag(path.target(1.5)), 1.25
    )
    assert np.allclose(np.diag(path.target(2.5)), [1.75, 1.75, 2.25]) and np.allclose(
        np.diag(path.target(9)), [3, 3, 4]
    )
    assert (
        path.duration == 3.0
        and np.count_nonzero(path.target(2.5) - np.diag(np.diag(path.target(2.5)))) == 0
    )
    ramp = pressure_control(2.0, 1.0, 0.5, rate=1.0, band=1.0, unload_to=1.0, unload=0.5)
    assert ramp.duration == 2.5
    assert [ramp.target(t)[0, 0] for t in (0.5, 1.2, 1.75, 2.4)] == pytest.approx(
        [1.0, 2.0, 1.5, 1.0]
    )
    # the corners are rounded over 10 % of the shorter segment: C1, off the corner by
    # |rate change| w / 8
    rounded = [np.diag(path.target(t))[0] for t in (0.95, 0.9999, 1.0, 1.0001, 1.05)]
    assert rounded[0] == pytest.approx(1.9) and rounded[4] == pytest.approx(1.925)
    assert rounded[2] == pytest.approx(2.0 - 3.5 * 0.1 / 8) and abs(rounded[3] - rounded[1]) < 1e-3
    for times, stresses, match in (
        ([0, 1, 1], [0, 1, 2], "increase strictly"),
        ([0, 1], [0, 1, 2], "one"),
        ([0, np.nan], [0, 1], "finite"),
        ([-1, 1], [0, 1], "start >= 0"),
    ):
        with pytest.raises(ValueError, match=match):
            normal_stress_path(times, stresses, rate=1.0, band=1.0)


def synthetic_rupture_history(n=40):
    """A probe's history as a stress path meets its strength: the axial tension rises linearly to
    3 MPa at row 25, then drops while the axial strain accelerates; E_c grows 100-fold from row
    20."""
    from types import SimpleNamespace

    t = 1e-3 + 1e-5 * np.arange(n)
    s33 = np.where(np.arange(n) <= 25, -0.12 * np.arange(n), -3.0 + 0.05 * (np.arange(n) - 25))
    h33 = np.where(np.arange(n) <= 25, 1e-4 * np.arange(n), 2.5e-3 + 2e-3 * (np.arange(n) - 25))
    E_c = 1e-6 * np.exp(np.clip(np.arange(n) - 20, 0, 6) * np.log(100) / 6)
    cols = {"time": t, "E_c": E_c, "E_d": np.full(n, 1e-2)}
    for i in (1, 2, 3):
        for j in (1, 2, 3):
            cols[f"sigma_schmidt_{i}{j}"] = s33 if (i, j) == (3, 3) else np.zeros(n)
            cols[f"F{i}{j}"] = np.exp(h33) if (i, j) == (3, 3) else np.full(n, float(i == j))
    cols["time"] = np.concatenate([[0.5e-3], t[1:]])  # the first row belongs to the consolidation
    return SimpleNamespace(column=lambda name: cols[name])


def test_force_rupture_analysis(tmp_path):
    """Force-controlled rupture: E_c / E_d (eq. 4.14) reaches phi_c while the kinetic energy grows,
    W2 (eq. 4.15) turns <= 0 at the stress peak, the path stress is the projection on the path;
    outputs written; bad cases refused before any computation."""
    from mpfem_fenicsx.workflows.force_rupture import (
        ForceRuptureCase,
        phi_quasi_static,
        rupture_points,
        rupture_rows,
        write_outputs,
    )

    history = synthetic_rupture_history()
    start, final = np.zeros(3), np.array([0.0, 0.0, -6.0])
    rows = rupture_rows(history, 0.5e-3, start, final, w2_window=0)
    # row 25 of the history
    assert rows["time"].size == 39 and rows["path_stress"][24] == pytest.approx(3.0)
    assert rows["phi"][0] == pytest.approx(1e-4) and phi_quasi_static(rows) == pytest.approx(1e-4)
    points = rupture_points(rows, phi_c=1e-3)
    # E_c / E_d = 1e-4 100^((k - 20) / 6) reaches 1e-3 at k = 23 (+ 0.0 rows)
    assert points["phi"]["time"] == pytest.approx(history.column("time")[23], rel=1e-9)
    assert points["peak"]["sigma_33"] == pytest.approx(-3.0) and points["peak"][
        "sigma_m"
    ] == pytest.approx(-1.0)
    assert points["w2"]["path_stress"] > 2.9 and points["w2"]["time"] >= points["peak"]["time"]
    assert points["phi"]["time"] < points["w2"]["time"]
    assert "phi" not in rupture_points(rows, phi_c=0.5)
    case = ForceRuptureCase(
        base=CompactionCase.build(condition="CLP", gamma=1e-2), out_dir=str(tmp_path)
    )
    write_outputs(tmp_path, rows, points, case)
    assert (tmp_path / "force_rupture.png").stat().st_size > 1000
    assert (tmp_path / "rupture_points.csv").read_text().count("\n") == 4
    with pytest.raises(ValueError, match="without adhesion"):
        ForceRuptureCase(base=CompactionCase.build(condition="CLP"))
    with pytest.raises(ValueError, match="final_stress must hold 3"):
        ForceRuptureCase(
            base=CompactionCase.build(condition="CLP", gamma=1e-2), final_stress=(1.0, 2.0)
        )
    with pytest.raises(ValueError, match="phi_c = 2.0 is out of range: must be > 0 and < 1"):
        ForceRuptureCase(base=CompactionCase.build(condition="CLP", gamma=1e-2), phi_c=2.0)


@pytest.mark.heavy
def test_force_rupture_where_strain_tangent_falls_below_servo(tmp_path):
    """Two realizations of one limit load: the adhesive simple cubic cell (gamma = 1e-2 mJ/mm^2),
    consolidated to 2 MPa and unloaded to 0.2 MPa, pulled along z with the lateral stresses held at
    0.2 MPa, (a) under force control (sigma_33 driven at 6.2 MPa/ms towards -6 MPa) and (b)
    strain-driven, slowly (F33 at 5 1/s). The adhesive necks yield and harden: (b) has no peak but
    a knee. Force control holds the path only while the servo's largest strain rate can deliver the
    stress rate asked, i.e. while the tangent modulus K_t of (b) exceeds 6.2 MPa/ms / 100 1/s =
    62 MPa: E_c / E_d must leave its quasi-static level where K_t crosses 62 MPa. Measured
    (2026-11-25): the strain-driven K_t crosses 62 MPa near sigma_33 = -3.0 MPa, E_c / E_d reaches
    1e-3 at -3.06 MPa (-3.14 MPa with a 4x slower ramp, where K_t = 15.5 MPa is crossed near
    -3.12 MPa); W2 turns <= 0 at the peak, -3.46 MPa (the servo, saturated, strains at 100 1/s)."""
    from mpfem_fenicsx.workflows.force_rupture import ForceRuptureCase, run_force_rupture
    from mpfem_fenicsx.workflows.stress_probes import consolidate, run_probe

    base = small_case(
        tmp_path, condition="CLP", duration=1e-3, increments=1000, outputs=10, gamma=1e-2
    )
    case = ForceRuptureCase(
        base=base,
        p_load=2.0,
        p_probe=0.2,
        final_stress=(0.2, 0.2, -6.0),
        rows_per_probe=40,
        out_dir=str(tmp_path / "force"),
    )
    result = run_force_rupture(case, MPI.COMM_SELF, log=quiet)
    points, rows = result["points"], result["rows"]
    assert result["phi_quasi_static"] < 0.1 * case.phi_c and np.nanmax(rows["phi"]) > 3 * case.phi_c
    assert points["phi"]["time"] < points["w2"]["time"]
    # MPa per row
    row_step = np.linalg.norm(np.subtract(case.final_stress, case.p_probe)) / case.rows_per_probe
    assert abs(points["w2"]["path_stress"] - points["peak"]["path_stress"]) < row_step
    # (b) strain-driven from the same consolidated state (a new consolidation: the same run)
    state = consolidate(replace(case, out_dir=str(tmp_path / "strain")), MPI.COMM_SELF, log=quiet)
    rate, strain = 5.0, 0.012
    pull = StressControl(
        duration=state.time + strain / rate,
        stress_driven=np.diag([True, True, False]),
        target=lambda t: 0.2 * np.eye(3),
        velocity_gradient=lambda t: np.diag([0.0, 0.0, rate]),
        **case.servo(),
    )
    h = run_probe(
        replace(case, probe=strain / rate / 1e-3, rows_per_probe=20),
        state,
        pull,
        "pull",
        MPI.COMM_SELF,
        log=quiet,
    )
    after = h.column("time") > state.time * (1 + 1e-12)
    tension, h33 = -h.column("sigma_schmidt_33")[after], np.log(h.column("F33")[after])
    K_t = np.diff(tension) / np.diff(h33)  # MPa, between rows
    # MPa: the stress rate asked over the servo's largest strain rate
    limit = 6.2 / 1e-3 / case.servo()["rate"]
    k = int(np.argmax((K_t < limit) & (np.arange(K_t.size) > 0)))
    assert k > 0 and K_t[k - 1] >= limit, K_t
    # the stress across the row where K_t crosses
    knee = tension[k] + (tension[k + 1] - tension[k]) * 0.5
    assert -points["phi"]["sigma_33"] == pytest.approx(knee, rel=0.05), (points["phi"], knee, K_t)


def test_force_rupture_demo_refuses_bad_input():
    """demos/force_rupture.py exits 2 with one line naming the field, before any computation."""
    import subprocess
    import sys
    from pathlib import Path

    demo = Path(__file__).parents[1] / "demos" / "force_rupture.py"
    for args, words in (
        (["--gamma", "0"], "without adhesion"),
        (["--final", "1", "2"], "expected 3"),
        (["--p-probe", "5"], "p_probe must be in"),
    ):
        run = subprocess.run(
            [sys.executable, str(demo), *args], capture_output=True, text=True, timeout=300
        )
        assert run.returncode == 2 and words in run.stderr, (args, run.stderr)
