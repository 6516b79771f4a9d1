"""The contact law at single points (thesis §3.3): branches, memory, forced degree of contact."""

import numpy as np
import pytest

from mpfem_fenicsx.contact.kernels import slip_reversal_limit, trial_shear
from mpfem_fenicsx.contact.laws import ContactLaw, evaluate_law


def _law(law, gap, smax=0.0, slip=(0.0, 0.0, 0.0), tt=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)):
    n = len(gap)
    out = [
        np.empty(n),
        np.empty((n, 3)),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n, np.int64),
    ]
    evaluate_law(
        np.asarray(gap, float),
        np.tile(slip, (n, 1)).astype(float),
        np.tile(normal, (n, 1)).astype(float),
        np.zeros(n),
        np.full(n, smax, float),
        np.tile(tt, (n, 1)).astype(float),
        *law.kernel_parameters(),
        *out,
    )
    T1, Tt, alpha, smax_new, dissipation, branch = out
    return T1, Tt, alpha, smax_new, dissipation


def test_normal_law_branches_and_memory():
    law = ContactLaw(penalty=1e9, friction=0.0, gamma=1e-2, delta_max=2e-4, asperity_yield=200.0)
    T1, _, alpha, smax, _ = _law(law, [-6e-7])  # T1 = 600 = p0: alpha = 1/2
    assert (
        T1[0] == pytest.approx(600.0)
        and alpha[0] == pytest.approx(0.5)
        and smax[0] == pytest.approx(600.0)
    )
    d1 = 0.5 * law.sigma_c / law.penalty
    gaps = [0.5 * d1, d1, 0.5 * (d1 + law.delta_max), law.delta_max, 2 * law.delta_max]
    T1, _, alpha, smax, _ = _law(law, gaps, smax=600.0)
    assert T1[1] == pytest.approx(-0.5 * law.sigma_c)  # peak tension alpha sigma_c
    assert T1[0] == pytest.approx(-0.25 * law.sigma_c)  # penalty line in tension
    assert T1[2] == pytest.approx(-0.25 * law.sigma_c)  # halfway down the softening line
    assert T1[3] == 0.0 and T1[4] == 0.0
    assert alpha[4] == 0.0 and smax[4] == 0.0  # memory erased beyond delta_max
    assert alpha[2] == pytest.approx(0.5)  # kept before delta_max


def test_forced_degree_of_contact_only_where_contact_was_made():
    law = ContactLaw(penalty=1e9, friction=0.0, gamma=1e-3, delta_max=1e-5, alpha_forced=1.0)
    never, _, a_never, _, _ = _law(law, [5e-6], smax=0.0)
    assert never[0] == 0.0 and a_never[0] == 0.0  # no snap-in ahead of the contact
    touched, _, a_touched, _, _ = _law(law, [law.sigma_c / law.penalty], smax=100.0)
    assert touched[0] == pytest.approx(-law.sigma_c) and a_touched[0] == 1.0


def test_coulomb_stick_slip_and_dissipation():
    law = ContactLaw(penalty=1e9, friction=0.1)
    gap = [-1e-7]  # T1 = 100 MPa, tau_c = 10 MPa
    _, Tt, _, _, w = _law(law, gap, slip=(5e-9, 0.0, 0.0))  # trial 5 MPa: stick
    assert Tt[0] == pytest.approx([-5.0, 0.0, 0.0]) and w[0] == 0.0
    _, Tt, _, _, w = _law(law, gap, slip=(3e-8, 0.0, 0.0))  # trial 30 MPa: slip at 10
    assert Tt[0] == pytest.approx([-10.0, 0.0, 0.0])
    assert w[0] == pytest.approx(10.0 * (3e-8 - 1e-8))  # tau_c x slip part of the increment
    _, Tt, _, _, _ = _law(law, [1e-7], slip=(3e-8, 0.0, 0.0))  # opening: no shear
    assert np.all(Tt[0] == 0.0)
    _, Tt, _, _, _ = _law(law, gap, slip=(0.0, 0.0, 1e-6))  # normal motion is not slip
    assert np.all(Tt[0] == 0.0)


def test_adhesive_peak_must_open_before_delta_max():
    """alpha sigma_c / k >= delta_max leaves no softening branch: rejected, naming the fields."""
    # peak at 1e-7 mm: fine
    ContactLaw(penalty=1e9, gamma=1e-2, delta_max=2e-4).require_softening_branch()
    with pytest.raises(
        ValueError,
        match=r"contact.gamma = 0.01 with contact.delta_max = 0.0005 .* must be < "
        r"delta_max \(gamma < k delta_max\^2 / 2 = 0.000125 mJ/mm\^2\)",
    ):
        # sigma_c / k = 0.04 mm
        ContactLaw(penalty=1e3, gamma=1e-2, delta_max=5e-4).require_softening_branch()
    with pytest.raises(ValueError, match="alpha sigma_c / k = 0.02 mm"):
        ContactLaw(
            penalty=1e3, gamma=1e-2, delta_max=5e-4, alpha_forced=0.5
        ).require_softening_branch()
    # no adhesion
    ContactLaw(penalty=1e3, gamma=1e-2, delta_max=5e-4, alpha_forced=0.0).require_softening_branch()


@pytest.mark.parametrize("theta", [0.05, 0.3])
def test_stored_tangential_traction_rotates_with_contact_frame(theta):
    """A sticking point whose normal turns by theta (the contact rolls) keeps its
    tangential traction's magnitude: the stored traction is rotated into the new tangent plane, not
    projected on it (which shrank it by cos theta and released stored shear without any slip)."""
    law = ContactLaw(penalty=1e9, friction=0.1)  # T1 = 100 MPa: stick below 10 MPa
    stored = np.array([-5.0, 0.0, 0.0])  # MPa, in the old tangent plane (normal e3)
    normal = (np.sin(theta), 0.0, np.cos(theta))  # turned towards the stored traction
    _, Tt, _, _, w = _law(law, [-1e-7], tt=stored, normal=normal)
    assert np.linalg.norm(Tt[0]) == pytest.approx(5.0, rel=1e-12)
    assert Tt[0] @ normal == pytest.approx(0.0, abs=1e-12)  # in the new tangent plane
    # the rotated vector
    assert Tt[0] == pytest.approx(-5.0 * np.array([np.cos(theta), 0.0, -np.sin(theta)]))
    assert w[0] == 0.0
    # a traction along the rotation axis is unchanged
    _, Tt, _, _, _ = _law(law, [-1e-7], tt=(0.0, 3.0, 0.0), normal=normal)
    assert Tt[0] == pytest.approx([0.0, 3.0, 0.0])


def test_trial_shear_recovered_from_the_returned_traction_and_dissipation():
    """|T_t,trial| = |T_t| + k_t w / |T_t| for a slipping point (its trial is known here: the
    stored traction minus k_t x the slip), |T_t| for a sticking one."""
    law = ContactLaw(penalty=1e9, friction=0.1)
    kt = law.kernel_parameters()[1]
    for slip, trial in ((3e-8, 30.0), (7e-8, 70.0), (5e-9, 5.0)):
        _, Tt, _, _, w = _law(law, [-1e-7], slip=(slip, 0.0, 0.0))
        assert trial_shear(Tt, w, kt)[0] == pytest.approx(trial)


def test_newton_update_reverses_a_slipping_point_at_most_to_its_cone_centre():
    """The limited update, applied to the law, leaves the point's trial traction on its side
    of the cone's centre, and a slip continued along its direction is not limited."""
    law = ContactLaw(penalty=1e9, friction=0.1)
    kt = law.kernel_parameters()[1]
    slip = 3e-8  # trial 30 MPa, slips at 10 MPa
    _, Tt, _, _, w = _law(law, [-1e-7], slip=(slip, 0.0, 0.0))
    branch = np.array([4 * 2 + 0])  # slip, overlap
    normal = np.array([[0.0, 0.0, 1.0]])
    trial = trial_shear(Tt, w, kt)
    update = np.array([[-1e-7, 0.0, 5e-9]])  # back by 1e-7 mm (trial to -70 MPa) + a normal part
    lam = slip_reversal_limit(update, normal, Tt, trial, branch, kt)
    assert lam == pytest.approx(0.3)  # 3e-8 of the 1e-7 mm back: the trial to 0
    _, Tt_after, _, _, _ = _law(law, [-1e-7], slip=(slip + lam * update[0, 0], 0.0, 0.0))
    assert Tt_after[0, 0] == pytest.approx(0.0, abs=1e-9)  # stick, at the centre
    onward = np.array([[1e-6, 0.0, 0.0]])
    assert slip_reversal_limit(onward, normal, Tt, trial, branch, kt) == 1.0
    stick = np.array([4 * 1 + 0])
    assert slip_reversal_limit(update, normal, Tt, trial, stick, kt) == 1.0


def test_guards_leave_memory_to_the_converged_state_and_snap_a_cycling_point_on_its_third_return():
    """Within one Newton increment: an iterate that carries an adhered point beyond delta_max
    (branch SEPARATED) erases nothing, so a later iterate finds it adhered again; a point that
    leaves softening for the loading line three times is snapped off (memory erased), or, the
    snap not allowed, keeps its memory and is recorded as refused."""
    from mpfem_fenicsx.contact.guards import AdhesiveGuards
    from mpfem_fenicsx.contact.laws import ADHESIVE_LOADING, SEPARATED, SOFTENING

    keys, smax = np.array([7]), np.array([300.0])

    def iterate(guards, code):
        branch = np.array([code])
        guards.track(keys, branch, smax, np.zeros(1))
        guards.remember(keys, branch)
        alpha_n, smax_n = np.array([0.4]), smax.copy()
        guards.adjust_history(keys, alpha_n, smax_n)
        return smax_n[0]

    overshoot = AdhesiveGuards()
    assert [iterate(overshoot, c) for c in (SOFTENING, SEPARATED, SOFTENING)] == [300.0] * 3
    cycling = AdhesiveGuards()
    memory = [iterate(cycling, c) for c in (SOFTENING, ADHESIVE_LOADING) * 3]
    assert memory == [300.0] * 5 + [0.0]  # erased at the third return only
    cycling.reset()
    assert iterate(cycling, SOFTENING) == 300.0  # a new increment starts from the committed state
    # snap-off not allowed (a Newton increment longer than SNAP_INCREMENT of the nominal one):
    # the third return keeps the memory and is recorded for the solver to cut the increment back
    refused = AdhesiveGuards()
    refused.snap_allowed = False
    memory = [iterate(refused, c) for c in (SOFTENING, ADHESIVE_LOADING) * 3]
    assert memory == [300.0] * 6 and refused.refused.tolist() == [7]
    refused.reset()
    assert refused.refused.size == 0 and not refused.snap_allowed  # the solver's choice stays
