"""Closed-die compaction and the box of six planes: the punches' stages, the green-density
distribution, bad input, and small runs whose tools balance at rest."""

import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.workflows.box import PLANES, BoxCase, run_box, wall_paths
from mpfem_fenicsx.workflows.closed_die import (
    ClosedDieCase,
    balanced_push,
    density_bins,
    punch_paths,
    run_closed_die,
)


@pytest.mark.parametrize("action", ["single", "double"])
def test_punch_paths_press_to_the_target_then_eject_the_compact_out_of_the_die(action):
    case = ClosedDieCase(action=action, target_density=0.8, lift=0.05)
    height, radius, solid = 2.0, 0.5, 0.6  # poured density 0.6 / (pi 0.25 x 2) = 0.38
    upper, lower, pressed = punch_paths(case, height, solid, radius)
    t1, t2, t3, t4 = case.stage_ends
    assert pressed == pytest.approx(solid / (0.8 * np.pi * radius**2))
    gap = height + upper(t1)[2] - lower(t1)[2]  # between the punches at the end of pressing
    assert gap == pytest.approx(pressed)
    assert np.allclose(upper(t2), upper(t1)) and np.allclose(lower(t2), lower(t1))  # hold
    if action == "single":
        assert np.allclose(lower(t1), 0.0)
    else:  # both punches travel half-way
        assert lower(t1)[2] == pytest.approx(-upper(t1)[2])
    assert upper(t3)[2] - upper(t2)[2] == pytest.approx(0.05 * pressed)  # the retreat
    assert np.allclose(lower(t3), lower(t2))
    assert lower(t4)[2] == pytest.approx(height)  # the lower punch's face at the die's top
    # the upper punch ends a compact's height further away: clear of the ejected compact
    assert height + upper(t4)[2] - lower(t4)[2] == pytest.approx(gap + 1.05 * pressed)


def test_a_target_below_the_poured_density_is_refused():
    with pytest.raises(ValueError, match="target_density = 0.3 is below the poured density"):
        punch_paths(ClosedDieCase(target_density=0.3), 2.0, 0.6, 0.5)


def test_density_bins_of_a_uniformly_filled_die_are_uniform():
    """Cells of equal volume placed uniformly in a cylinder at solid fraction 0.7: every axial
    slice and every annulus of equal area holds 0.7 of its volume (an independent count)."""
    rng = np.random.default_rng(3)
    R, z0, z1, n = 2.0, 1.0, 4.0, 400_000
    r = R * np.sqrt(rng.random(n))
    theta = 2 * np.pi * rng.random(n)
    centroid = np.column_stack([r * np.cos(theta), r * np.sin(theta), rng.uniform(z0, z1, n)])
    volume = np.full(n, 0.7 * np.pi * R**2 * (z1 - z0) / n)
    bins = density_bins(volume, centroid, R, z0, z1, 4, MPI.COMM_SELF)
    assert np.allclose(bins["axial"], 0.7, rtol=0.01)
    assert np.allclose(bins["radial"], 0.7, rtol=0.01)
    # a denser bottom half shows in the axial bins only
    volume[centroid[:, 2] < 2.5] *= 1.2
    bins = density_bins(volume, centroid, R, z0, z1, 4, MPI.COMM_SELF)
    assert np.allclose(bins["axial"], [0.84, 0.84, 0.7, 0.7], rtol=0.01)
    assert np.allclose(bins["radial"], 0.77, rtol=0.01)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"target_density": 1.2}, "target_density = 1.2 is out of range"),
        ({"action": "triple"}, "action = 'triple' is not allowed"),
        ({"wall_friction": -0.1}, "wall_friction = -0.1 is out of range"),
        ({"increments": 0}, "increments = 0 is out of range"),
        ({"lift": 1.5}, "lift = 1.5 is out of range"),
    ],
)
def test_bad_closed_die_input_names_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ClosedDieCase(**kwargs)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"ratios": (1.0, -1.0, 1.0)}, "ratios"),
        ({"ratios": (0.0, 0.0, 0.0)}, "not all 0"),
        ({"fill": 0.7}, "fill = 0.7 is out of range"),
        ({"fill": 0.5, "target_density": 0.4}, "target_density = 0.4 must be > fill"),
    ],
)
def test_bad_box_input_names_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        BoxCase(**kwargs)


def test_the_demos_refuse_bad_options_with_one_line(root, tmp_path):
    for demo, option in (("closed_die", "--wall-friction=-1"), ("triaxial_box", "--fill=0.9")):
        run = subprocess.run(
            [sys.executable, str(root / "demos" / f"{demo}.py"), option, "--out", str(tmp_path)],
            capture_output=True,
            text=True,
        )
        assert run.returncode == 2, run.stderr
        assert len(run.stderr.strip().splitlines()) == 1


def test_box_walls_shorten_each_side_by_its_ratio_to_the_target_density():
    lengths, ratios = np.array([1.0, 2.0, 3.0]), (1.0, 0.5, 0.0)
    paths, final = wall_paths(lengths, ratios, 0.4, 0.6, 1.0, 1.2)
    assert np.prod(lengths) / np.prod(final) == pytest.approx(0.6 / 0.4)
    strains = np.log(final / lengths)
    assert strains[1] == pytest.approx(0.5 * strains[0]) and strains[2] == 0.0
    for (_, axis, side), path in zip(PLANES, paths, strict=True):
        move = path(1.2)
        assert np.count_nonzero(move) == (1 if ratios[axis] else 0)
        # the two planes of a side meet it half-way: its new length
        assert move[axis] * (1 if side == 0 else -1) == pytest.approx(
            0.5 * (lengths[axis] - final[axis])
        )


def test_a_small_closed_die_balances_its_tools_springs_back_and_is_ejected(tmp_path):
    """Six lead particles poured (0.34) and pressed to 0.5 in a die with wall friction 0.3: at the
    end of the hold the three tools' axial forces sum to zero (the compact at rest; a measure
    independent of each tool's force), the lower punch carries less than the upper one (the
    wall's friction), the compact springs back when the punch retreats, and is pushed out of
    the die (every node above the die's top at the end)."""
    case = ClosedDieCase(
        particles=6,
        seed=2,
        target_density=0.5,
        wall_friction=0.3,
        increments=5000,
        ramp=0.25,
        hold=0.3,
        unload=0.2,
        eject=0.5,
        outputs=12,
        out_dir=str(tmp_path),
    )
    result = run_closed_die(case, MPI.COMM_SELF, log=lambda *a: None, render=False)
    s = result.summary
    assert s["green_density_pressed"] == pytest.approx(0.5, rel=1e-9)
    assert abs(s["tools_force_sum_pressed"]) < 0.02
    assert 0 < s["transmission"] < 1.0
    assert s["die_normal_pressed"] > 0 and s["die_friction_pressed"] > 0
    assert s["springback"] > 0
    # this fast ejection (2500 increments) is inertial (the push 80 % out of balance): its
    # ejection force is NaN (balanced_push, tested below); the default's is measured in bench
    assert 0.0 <= s["ejection_balanced_share"] <= 1.0
    stage = result.history.column("stage")
    assert set(np.unique(stage)) == {1, 2, 3, 4}
    assert (tmp_path / "history.csv").is_file() and (tmp_path / "density_bins.csv").is_file()
    # the compact left the die: its lowest node at or above the die's top
    bottom = result.history.column("compact_bottom")
    assert bottom[-1] >= (1 - 1e-3) * s["fill_height"]
    assert bottom[0] == pytest.approx(0.0, abs=1e-3 * s["fill_height"])


def test_a_small_box_balances_opposite_planes_at_rest(tmp_path):
    """Six frictionless planes press six particles hydrostatically and hold: near rest every
    pair of opposite planes carries the same normal force (the compact's equilibrium, measured
    on two separate tools; 3.2 / 1.9 / 1.5 % apart after a hold of one pressing time, the loose
    packing still relaxing)."""
    case = BoxCase(
        particles=6,
        fill=0.35,
        target_density=0.55,
        increments=4000,
        hold=1.0,
        outputs=6,
        out_dir=str(tmp_path),
    )
    history, summary = run_box(case, MPI.COMM_SELF, log=lambda *a: None, render=False)
    forces = [summary[f"{name}_N"] for name, _, _ in PLANES]
    for a in range(3):
        assert forces[2 * a] > 0
        assert forces[2 * a] == pytest.approx(forces[2 * a + 1], rel=0.05)
    assert summary["rho"] == pytest.approx(0.55, rel=1e-9)
    assert summary["quasi_static"]


def test_a_die_case_file_is_validated_like_the_others(tmp_path, capsys):
    """``[die]`` and ``[box]`` case files: their keys checked against the cases' declarations
    (one line naming the key, exit 2), a valid one accepted by ``--check``."""
    from mpfem_fenicsx.cli.main import main

    good = tmp_path / "die.toml"
    good.write_text('[die]\nparticles = 20\nwall_friction = 0.3\naction = "double"\n')
    assert main(["run", str(good), "--check"]) == 0
    assert "valid: ClosedDieCase of 20 particles" in capsys.readouterr().out
    box = tmp_path / "box.toml"
    box.write_text("[box]\nratios = [1, 0.5, 0.25]\ntarget_density = 0.7\n")
    assert main(["run", str(box), "--check"]) == 0
    for text, message in (
        ("[die]\nwall_friction = -1\n", "[die] wall_friction = -1.0 is out of range"),
        ("[die]\nparticles = 2.5\n", "[die] particles = 2.5 has the wrong type"),
        ("[die]\npunch = 1\n", "unknown key [die] punch"),
        ("[die]\n[packing]\nparticles = 3\n", "[die] is a case of its own: remove [packing]"),
        ("[box]\nratios = [1, 2]\n", "[box] ratios = [1, 2] must be a list of 3 numbers"),
        ("[box]\nfill = 0.5\ntarget_density = 0.4\n", "[box] target_density = 0.4 must be > fill"),
    ):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        assert main(["run", str(bad)]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1, err


def test_the_ejection_force_counts_only_where_the_tools_balance():
    """(upper, lower, die) axial forces on the tools: the compact sliding at constant speed
    (the wall's friction holds the push) gives the push; an accelerating compact (its inertia
    carries 80 % of the push) or a punch carrying nothing gives NaN."""
    assert balanced_push(np.array([0.0, -0.0278, 0.0277])) == pytest.approx(0.0278)
    assert np.isnan(balanced_push(np.array([0.0, -0.275, 0.051])))
    assert np.isnan(balanced_push(np.zeros(3)))
    assert balanced_push(np.array([0.0, -1.0, 0.9]), limit=0.2) == 1.0
