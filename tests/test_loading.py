"""Amplitudes and macroscopic gradient paths (loading/)."""

import numpy as np
import pytest

from mpfem_fenicsx.loading import (
    PROFILES,
    GradientPath,
    SmoothRamps,
    SmoothStep,
    compaction_gradient,
)


@pytest.mark.parametrize("name", tuple(PROFILES))
def test_amplitude_goes_0_to_1_and_rate_is_its_derivative(name):
    amplitude = PROFILES[name](3.0, 1.0)
    t = np.linspace(0.5, 3.5, 60001)  # beyond both knots: held at 0 and 1
    a = np.array([amplitude(x) for x in t])
    rate = np.array([amplitude.rate(x) for x in t])
    assert a[0] == 0.0 and a[-1] == 1.0
    assert np.all(np.diff(a) >= 0.0)
    # central differences of a against the analytic rate (C1 everywhere, zero at the knots)
    assert np.abs(np.gradient(a, t) - rate).max() < 1e-6
    assert amplitude.rate(1.0) == pytest.approx(0.0, abs=1e-12)
    assert amplitude.rate(3.0) == pytest.approx(0.0, abs=1e-12)


def test_smooth_ramps_plateau_and_where_the_smooth_step_peaks():
    ramps, step = SmoothRamps(1.0), SmoothStep(1.0)
    # plateau 1 / (1 - (0.1 + 0.3) / 2) = 1.25 x the mean rate, over s in [0.1, 0.7]
    assert ramps.plateau == pytest.approx(1.25)
    for s in (0.1, 0.4, 0.7):
        assert ramps.rate(s) == pytest.approx(1.25)
    assert ramps(0.4) == pytest.approx(1.25 * (0.05 + 0.3))
    # the smooth step's mid-path rate is 1.875 x the mean: 1.5 x the plateau
    assert step.rate(0.5) / ramps.rate(0.5) == pytest.approx(1.5)


@pytest.mark.parametrize("rise, fall", [(0.0, 0.3), (0.1, 0.0), (0.6, 0.5)])
def test_smooth_ramps_rejects_bad_fractions(rise, fall):
    with pytest.raises(ValueError, match="rise > 0, fall > 0 and rise \\+ fall <= 1"):
        SmoothRamps(1.0, rise=rise, fall=fall)


def test_gradient_path_profile_per_segment():
    G = compaction_gradient("isotropic", 0.6, 0.9)
    unload = np.eye(3) * 1.01
    ramps = GradientPath([(1.0, G), (1.0, unload)], profiles=("smooth-ramps",))
    step = GradientPath([(1.0, G), (1.0, unload)])

    def h(F):  # fraction of the compaction's Hencky strain
        return np.log(F[0, 0]) / np.log(G[0, 0])

    assert h(ramps(0.4)) == pytest.approx(SmoothRamps(1.0)(0.4))
    assert h(step(0.4)) == pytest.approx(SmoothStep(1.0)(0.4))
    # both end each segment at the same gradient; the second segment keeps the smooth step
    for t in (1.0, 2.0):
        assert np.allclose(ramps(t), step(t))
    assert np.allclose(ramps(1.5), step(1.5))
    with pytest.raises(
        ValueError, match="profile must be one of smooth-step, smooth-ramps, got 'linear'"
    ):
        GradientPath([(1.0, G)], profiles=("linear",))
    with pytest.raises(ValueError, match="2 profiles for 1 segments"):
        GradientPath([(1.0, G)], profiles=("smooth-step", "smooth-step"))


def test_compaction_case_profiles_its_further_segments():
    """CompactionCase.segment_profiles shapes ``segments_after`` in time (after the compaction and
    a hold, which keep theirs); a name or count that does not fit is refused before any run."""
    from mpfem_fenicsx.workflows.compaction import CompactionCase, loading_path

    unload = (1e-4, np.eye(3) * 1.01)
    case = CompactionCase.build(
        hold=0.5, segments_after=(unload,), segment_profiles=("smooth-ramps",), visual=False
    )
    path = loading_path(case.loading, 0.6)
    t0 = case.loading.duration * 1.5  # the unload starts after the compaction and its hold
    fraction = np.log(path(t0 + 0.4e-4)[0, 0] / path(t0)[0, 0]) / np.log(1.01)
    assert fraction == pytest.approx(SmoothRamps(1e-4)(0.4e-4))
    assert np.allclose(
        path(case.loading.duration * 1.25), path(case.loading.duration)
    )  # the hold holds
    with pytest.raises(
        ValueError, match="segment_profiles must name one of smooth-step, smooth-ramps"
    ):
        CompactionCase.build(segments_after=(unload,), segment_profiles=("linear",))
    with pytest.raises(ValueError, match="for at most the 0 segments_after"):
        CompactionCase.build(segment_profiles=("smooth-ramps",))
