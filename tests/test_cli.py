"""The `mpfem` command line: case-file validation, an end-to-end run with its outputs,
figures drawn again, a forced divergence, and restart from a checkpoint."""

import shutil
import subprocess

import numpy as np
import pytest
from mpfem_fenicsx.meshes.packing import read_packing as read_packing_file

from mpfem_fenicsx.cli.casefile import SCHEMA, example_case, load_case
from mpfem_fenicsx.cli.main import main
from mpfem_fenicsx.io import read_csv
from test_parameters import just_outside  # the values a declared range must refuse

TINY = "demos/cases/tiny.toml"
#: its [solver] increments (a multiple of 30: rows every 15 of them in the forced divergence,
#: checkpoints at half of them and at the end)
TINY_STEPS = 1800


def _case(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


BAD_CASES = [
    # (case text, words the one-line error must contain)
    ("[contact]\nfrction = 0.1\n", ["unknown key", "[contact] frction", "friction"]),
    ("[solvr]\nkind = 'explicit'\n", ["unknown section", "[solvr]"]),
    ("[packing]\nparticles = 'fifty'\n", ["[packing] particles", "wrong type", "integer"]),
    ("[packing]\nparticles = 50.5\n", ["[packing] particles", "wrong type"]),
    ("[packing]\nr_min = -0.1\n", ["[packing] r_min", "-0.1", "out of range", "> 0"]),
    ("[packing]\nr_min = 0.2\nr_max = 0.1\n", ["[packing] r_max", "r_min"]),
    ("[loading]\ntarget_density = 1.0\n", ["[loading] target_density", "< 1"]),
    ("[loading]\ntarget_density = 0.0\n", ["[loading] target_density", "> 0"]),
    ("[contact]\nfriction = -0.1\n", ["[contact] friction", ">= 0"]),
    ("[contact]\ngamma = -1e-3\n", ["[contact] gamma", ">= 0", "mJ/mm^2"]),
    (
        "[boundary]\ncondition = 'PBC'\n",
        ["[boundary] condition", "'PBC'", "'GDH', 'GDF', 'CLPS', 'CLP'"],
    ),
    ("[boundary]\ncondition = 'GDF'\nimages = true\n", ["[boundary] images", "CLP"]),
    ("[material]\nnu = 0.5\n", ["[material] nu", "< 0.5"]),
    ("[solver]\nincrements = 5\n", ["[solver] increments", ">= 10"]),
    ("[solver]\nlocal_damping = 1.0\n", ["[solver] local_damping", "< 1"]),
    ("[loading]\nhold = -0.1\n", ["[loading] hold", ">= 0"]),
    ("[loading]\nprofile = 'linear'\n", ["[loading] profile", "'smooth-step', 'smooth-ramps'"]),
    ("[mesh]\nresolution = 'fine'\n", ["[mesh] resolution", "'chapter2', 'chapter4', 'coarse'"]),
    ("[packing]\nfile = 'missing.txt'\n", ["[packing] file", "no such file"]),
    ("[loading\n", ["not valid TOML"]),
    (
        "[control]\npath = 'shear'\n",
        ["[control] path", "'none', 'pressure', 'triaxial', 'cycle', 'lode'"],
    ),
    ("[control]\npath = 'cycle'\npressure = 2.0\n", ["[control] unload_to", "required"]),
    (
        "[control]\npath = 'cycle'\npressure = 2.0\nunload_to = 3.0\n",
        ["[control] unload_to", "below pressure"],
    ),
    (
        "[control]\npath = 'cycle'\npressure = 2.0\nunload_to = 1.0\nreload_to = 0.5\n",
        ["reload_to", "above"],
    ),
    ("[control]\npath = 'lode'\npressure = 2.0\n", ["[control] q_max", "required"]),
    (
        "[control]\npath = 'lode'\npressure = 2.0\nq_max = 1.0\nlode_angle = 400\n",
        ["[control] lode_angle", "<= 360"],
    ),
    ("[control]\npath = 'pressure'\npressure = 2.0\nq_max = 1.0\n", ["[control] q_max", "lode"]),
    (
        "[control]\npath = 'lode'\npressure = 2.0\nq_max = 1.0\nunload_to = 1.0\n",
        ["[control] unload_to", "cycle"],
    ),
    ("[control]\npath = 'triaxial'\n", ["[control] pressure", "required"]),
    ("[control]\npressure = 2.0\n", ["[control] pressure", "needs a [control] path"]),
    ("[control]\npath = 'triaxial'\npressure = -2.0\n", ["[control] pressure", "> 0"]),
    (
        "[control]\npath = 'triaxial'\npressure = 2.0\naxial_strain = 0.8\n",
        ["[control] axial_strain", "<= 0.5"],
    ),
    (
        "[control]\npath = 'pressure'\npressure = 2.0\naxial_strain = 0.1\n",
        ["[control] axial_strain", "triaxial"],
    ),
    (
        "[control]\npath = 'triaxial'\npressure = 2.0\nmeasure = 'lw'\n",
        ["[control] measure", "'schmidt', 'volume'"],
    ),
    (
        "[control]\npath = 'triaxial'\npressure = 2.0\nintegral_time = -1.0\n",
        ["[control] integral_time", ">= 0"],
    ),
    (
        "[control]\npath = 'pressure'\npressure = 2.0\n[boundary]\ncondition = 'GDF'\n",
        ["control", "CLP or CLPS"],
    ),
]


@pytest.mark.parametrize("text, words", BAD_CASES)
def test_bad_case_exits_2_naming_the_field(tmp_path, capsys, text, words):
    code = main(["run", _case(tmp_path, text)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and err.startswith("mpfem: error: ")
    for w in words:
        assert w in err, (w, err)


def _packing_file(tmp_path, rows, cell=1.0):
    path = tmp_path / "packing.txt"
    path.write_text(
        f"{cell} {cell} {cell}\n" + "".join(f"{x} {y} {z} {r}\n" for x, y, z, r in rows)
    )
    return path


@pytest.mark.parametrize(
    "rows, words",
    [
        (
            [(0.2, 0.2, 0.2, 0.1), (0.35, 0.2, 0.2, 0.1), (0.7, 0.7, 0.7, 0.1)],
            ["overlap", "0", "1"],
        ),
        ([(0.2, 0.2, 0.2, 0.1), (1.3, 0.5, 0.5, 0.1)], ["particle 1", "outside"]),
        ([(0.2, 0.2, 0.2, -0.1), (0.6, 0.6, 0.6, 0.1)], ["radius", "particle 0"]),
    ],
)
def test_bad_packing_file_is_rejected_with_sphere_indices(tmp_path, capsys, rows, words):
    _packing_file(tmp_path, rows)
    code = main(["run", _case(tmp_path, "[packing]\nfile = 'packing.txt'\n")])
    err = capsys.readouterr().err
    assert code == 2, err
    for w in words:
        assert w in err, (w, err)
    # the same check through `mpfem pack --input`
    assert (
        main(["pack", "--input", str(tmp_path / "packing.txt"), "--out", str(tmp_path / "o.txt")])
        == 2
    )


CHECK_REFUSES = [
    # (packing file text, case's [loading] lines, words of the one-line error): what `run` refuses
    (
        "1 1 1\n0.2 0.2 0.2 0.1\n0.3 0.2 0.2 0.1\n0.7 0.7 0.7 0.1\n",
        "",
        ["overlap of particles 0 and 1"],
    ),
    ("1 1 1\n0.2 0.2 0.2 0.1\n0.6 nan 0.6 0.1\n", "", ["particle 1", "outside the cell"]),
    ("1 1\n0.2 0.2 0.2 0.1\n", "", ["line 1", "cell line 'dx dy dz' must hold 3 numbers"]),
    ("", "", ["expected a cell line"]),
    ("1 1 1\n0.2 0.2 0.2 0.6\n", "", ["radius must be < min(cell)/2", "particle 0"]),
    (
        "0.4 0.4 0.4\n"
        + "".join(f"{x} {y} {z} 0.1\n" for x in (0.1, 0.3) for y in (0.1, 0.3) for z in (0.1, 0.3)),
        "[loading]\ntarget_density = 0.45\n",
        ["loading.target_density = 0.45", "0.508"],
    ),
]


@pytest.mark.parametrize("packing, loading, words", CHECK_REFUSES)
def test_check_refuses_what_run_refuses(tmp_path, capsys, packing, loading, words):
    (tmp_path / "packing.txt").write_text(packing)
    case = _case(tmp_path, "[packing]\nfile = 'packing.txt'\n" + loading)
    code = main(["run", case, "--check"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, (w, err)


def test_check_reads_a_dem_export_with_its_contact_overlaps(tmp_path, capsys):
    """A YADE export with its cell in a comment header and 0.12 % of a radius of contact overlap
    (a packing held under 10 kPa): valid for a run (the radius reduction lowered to remove it), the
    format and the reduction said; a 6 % overlap is refused."""
    r, gap = 0.1, 0.1 * (2 - 0.0012)
    rows = [(0.2, 0.2, 0.2), (0.2 + gap, 0.2, 0.2), (0.6, 0.6, 0.6)]
    header = "# dx dy dz (mm) = 1.0 1.0 1.0 ; solid_fraction = 0.0126 ; N = 3\n"
    (tmp_path / "yade.txt").write_text(header + "".join(f"{x} {y} {z} {r}\n" for x, y, z in rows))
    case = _case(tmp_path, "[packing]\nfile = 'yade.txt'\n[loading]\ntarget_density = 0.5\n")
    assert main(["run", case, "--check"]) == 0
    out = capsys.readouterr().out
    assert "read as yade" in out and "radius reduction x0.9893" in out, out
    assert "0.12 % overlaps" in out, out
    assert "valid: 3 particles from" in out, out
    assert (
        main(["pack", "--input", str(tmp_path / "yade.txt"), "--out", str(tmp_path / "ours.txt")])
        == 0
    )
    assert read_packing_file(tmp_path / "ours.txt", validate=False).cell.tolist() == [1.0] * 3
    rows[1] = (0.2 + 0.194, 0.2, 0.2)
    (tmp_path / "yade.txt").write_text(header + "".join(f"{x} {y} {z} {r}\n" for x, y, z in rows))
    assert main(["run", case, "--check"]) == 2
    assert "overlap of particles 0 and 1 (image shift [0, 0, 0]): 6 %" in capsys.readouterr().err


@pytest.mark.parametrize(
    "demo, args, words",
    [
        ("isotropic", ["--packing", "missing.txt"], ["No such file"]),
        ("simple_cubic", ["--radius", "-1"], ["radius must be > 0 mm"]),
        (
            "uniaxial",
            ["--log-strain", "-5"],
            ["--log-strain = -5.0 is out of range", "> 0 and <= 2"],
        ),
        ("hertz", ["--steps", "0"], ["--steps = 0 is out of range", ">= 1"]),
        (
            "sphere_squeeze",
            ["--reduction", "2"],
            ["--reduction = 2.0 is out of range", "> 0 and < 0.6"],
        ),
        ("two_spheres", ["--gamma", "-1"], ["contact.gamma", ">= 0"]),
        (
            "yield_surface",
            ["--target-density", "1.5"],
            ["--target-density = 1.5 is out of range", "> 0 and < 1"],
        ),
        ("triaxial", ["--particles", "1"], ["--particles = 1 is out of range", ">= 2 and <= 5000"]),
        ("triaxial", ["--restart", "nowhere"], ["restart: no checkpoint in nowhere"]),
        ("deviatoric_surface", ["--increments", "ten"], ["--increments: 'ten' is not an integer"]),
        (
            "triaxial",
            ["--rate", "100"],
            ["--rate = 100.0 is out of range", "> 0 and <= 10", "strain per duration"],
        ),
        ("deviatoric_surface", ["--p-probe", "3"], ["p_probe must be in (0, p_load = 2.0)"]),
        ("force_rupture", ["--phi-c", "2"], ["--phi-c = 2.0 is out of range", "> 0 and < 1"]),
        ("yield_surface", ["--nphi", "2"], ["--nphi = 2 is out of range", ">= 3 and <= 720"]),
        (
            "yield_surface",
            ["--reload-profile", "linear"],
            ["--reload-profile = 'linear' is not allowed", "'smooth-step', 'smooth-ramps'"],
        ),
    ],
)
def test_demos_exit_2_on_bad_input_like_mpfem(tmp_path, root, python, demo, args, words):
    proc = subprocess.run(
        [python, str(root / "demos" / f"{demo}.py"), *args, "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    err = proc.stderr.strip()
    assert proc.returncode == 2 and len(err.splitlines()) == 1 and f"{demo}.py: error: " in err, err
    for w in words:
        assert w in err, (w, err)


def test_dolfinx_imports_first_in_the_project_environment(tmp_path, root):
    """A user script whose first import is dolfinx (libmpi.so.12 sits in .venv/lib, which only
    mpi4py knew how to find): the bootstrap's .pth preloads it."""
    proc = subprocess.run(
        [
            str(root / ".venv" / "bin" / "python"),
            "-c",
            "import dolfinx, dolfinx.mesh\nfrom mpi4py import MPI\n"
            "m = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 1, 1, 1)\nprint(m.topology.dim)",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert proc.returncode == 0 and proc.stdout.strip() == "3", proc.stderr[-500:]


def test_unreachable_target_density_exits_2(tmp_path, capsys):
    # simple cubic cell: rho0 = pi / 6 * 0.99^3 = 0.508 (meshed radii) > the target
    _packing_file(
        tmp_path, [(x, y, z, 0.1) for x in (0.1, 0.3) for y in (0.1, 0.3) for z in (0.1, 0.3)], 0.4
    )
    code = main(
        [
            "run",
            _case(tmp_path, "[packing]\nfile = 'packing.txt'\n[loading]\ntarget_density = 0.45\n"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "loading.target_density = 0.45" in err and "0.508" in err, err


def test_example_case_is_valid_and_documents_every_key(tmp_path):
    text = example_case()
    for key in SCHEMA:
        assert f"[{key.section}]" in text and key.name in text
    case = load_case(_case(tmp_path, text))
    assert (case.boundary.condition, case.loading.target_density, case.output.directory) == (
        "CLP",
        0.92,
        "results/case",
    )
    assert main(["init", str(tmp_path / "case.toml")]) == 2  # refuses to overwrite


def test_control_keys_build_the_stress_control(tmp_path):
    """[control]: times and the servo's rate in units of the loading duration; the triaxial path's
    phases (all three normal stresses driven, then the lateral ones) and its targets."""
    case = load_case(
        _case(
            tmp_path,
            "[loading]\nduration = 2e-3\n[control]\npath = 'triaxial'\npressure = 3.0\n"
            "ramp = 0.5\nhold = 0.25\naxial_strain = 0.2\nrate = 0.2\nintegral_time = 0.05\n",
        )
    )
    control = case.loading.control
    assert control.duration == pytest.approx(2e-3 * (0.5 + 0.25 + 1.0))
    assert (
        control.rate == pytest.approx(100.0)
        and control.band == 0.75
        and control.integral_time == pytest.approx(1e-4)
    )
    assert np.array_equal(control.stress_driven(1e-3), np.eye(3, dtype=bool))
    assert np.array_equal(control.stress_driven(1.6e-3), np.diag([True, True, False]))
    assert np.allclose(control.target(0.5e-3), 1.5 * np.eye(3)) and np.allclose(
        control.target(3e-3), 3 * np.eye(3)
    )
    F = [
        control(t) for t in np.linspace(0.0, control.duration, 701)
    ]  # the servo phase, then the axial one
    assert F[-1][2, 2] == pytest.approx(
        np.exp(-0.2), rel=1e-5
    )  # servo idle: only the axial strain moves
    # the axial rate rises over the first 30 % of the axial phase (no jolt), then stays constant
    L = [control.velocity_gradient(t)[2, 2] for t in (1.5e-3 + 1e-9, 1.8e-3, 2.1e-3, 3.0e-3)]
    assert (
        L[0] == pytest.approx(0, abs=1e-3)
        and L[1] == pytest.approx(0.5 * L[2])
        and L[2] == pytest.approx(L[3])
    )
    pressure = load_case(
        _case(tmp_path, "[control]\npath = 'pressure'\npressure = 1.0\n", "p.toml")
    ).loading.control
    assert pressure.duration == pytest.approx(1.3e-3)  # the defaults: those of demos/triaxial.py
    assert pressure.band == 0.25 and pressure.integral_time == pytest.approx(1e-4)
    narrow = load_case(
        _case(
            tmp_path,
            "[control]\npath = 'pressure'\npressure = 1.0\nband_fraction = 0.15\n",
            "n.toml",
        )
    )
    assert narrow.loading.control.band == pytest.approx(
        0.15
    )  # a band given as a fraction of the pressure
    assert pressure.filter_time == pytest.approx(1e-5) and pressure.rate == pytest.approx(100.0)
    assert np.array_equal(pressure.stress_driven(1.2e-3), np.eye(3, dtype=bool))
    cycle = load_case(
        _case(
            tmp_path,
            "[control]\npath = 'cycle'\npressure = 2.0\nunload_to = 0.5\nreload_to = 3.0\n"
            "hold = 0.5\n",
            "c.toml",
        )
    ).loading.control
    assert cycle.duration == pytest.approx(4.5e-3)  # three ramps of 1e-3 s, three holds of 0.5e-3 s
    levels = [cycle.target(t)[0, 0] for t in (0.5e-3, 1.2e-3, 2e-3, 2.7e-3, 3.5e-3, 4.4e-3)]
    assert levels == pytest.approx([1.0, 2.0, 1.25, 0.5, 1.75, 3.0])
    lode = load_case(
        _case(
            tmp_path,
            "[control]\npath = 'lode'\npressure = 2.0\nq_max = 1.5\nlode_angle = 60\n"
            "hold = 0\nshear_time = 2\n",
            "l.toml",
        )
    ).loading.control
    from mpfem_fenicsx.homogenization import stress_invariants

    assert lode.duration == pytest.approx(3e-3) and np.allclose(lode.target(0.5e-3), np.eye(3))
    mean, q = stress_invariants(-lode.target(2e-3))
    assert mean == pytest.approx(2.0) and q == pytest.approx(0.75)  # half way through the shear
    end = np.diag(lode.target(3e-3))
    assert end[0] == pytest.approx(end[1]) and end[2] < end[0]  # 60 deg: triaxial extension along z


def test_restart_reads_history_rows_by_column_name():
    """Checkpoints list their history columns; older ones (without the list) predate the columns
    of _COLUMNS_ADDED, which restart as NaN."""
    from mpfem_fenicsx.workflows.compaction import CheckpointError, _history_rows

    columns = ["time", "Gamma", "Gamma_model", "E_p"]
    assert _history_rows({"history": [[1.0, 2.0, 4.0]]}, columns)[0][:2] == [1.0, 2.0]
    assert np.isnan(_history_rows({"history": [[1.0, 2.0, 4.0]]}, columns)[0][2])
    assert _history_rows({"history": [[4.0, 1.0]], "columns": ["E_p", "time"]}, columns)[0][
        ::3
    ] == [1.0, 4.0]
    with pytest.raises(CheckpointError, match="do not match"):
        _history_rows({"history": [[1.0, 2.0]]}, columns)


def test_restart_accepts_a_mesh_regenerated_to_round_off_not_another_partition():
    """A checkpoint names its owned dof coordinates: meshes regenerated on another machine
    differ by round-off (4e-16 mm measured) and restart; reordered or moved nodes do not."""
    from mpfem_fenicsx.workflows.compaction import _same_partition

    rng = np.random.default_rng(0)
    X = rng.uniform(0.0, 0.64, (500, 3))
    assert _same_partition(X, X + 4.4e-16 * rng.choice([-1.0, 1.0], X.shape))
    assert not _same_partition(X, X[rng.permutation(500)])  # another ordering / partition
    assert not _same_partition(X, X + np.where(np.arange(500)[:, None] == 7, 1e-3, 0.0))
    assert not _same_partition(X, X[:499])
    assert _same_partition(X[:0], X[:0])  # a rank without owned dofs


#: 50 spheres, contact overlaps up to 0.12 % of a radius (made by tests/test_packing.py's recipe)
YADE_50 = "tests/data/yade_50_overlapping.txt"
REDUCTION = "radius reduction x0.9895 (instead of x0.99) for the packing's 0.12 % overlaps"


def test_a_dem_export_runs_at_the_defaults(tmp_path, capsys, root):
    """The YADE fixture as it comes: `pack --input` and `run --check` accept it and say the
    radius reduction the run will use; the run (10 increments: a smoke run) builds at that
    reduction and ends with exit 0. Before the shared admission, pack and --check accepted it at
    0.99 and the run refused it (the 6x6 particle's nodes at 1.0100 x its radius)."""
    out = str(tmp_path / "ours.txt")
    assert main(["pack", "--input", str(root / YADE_50), "--out", out]) == 0
    assert REDUCTION in capsys.readouterr().out
    case = _case(
        tmp_path,
        f"[packing]\nfile = '{root / YADE_50}'\n[solver]\nincrements = 10\n"
        "[output]\noutputs = 1\nvisual = false\ncheckpoint_every = 0\n",
    )
    assert main(["run", case, "--check"]) == 0
    out = capsys.readouterr().out
    assert REDUCTION in out and "valid: 50 particles from" in out, out
    assert "rho0 0.6133 (radius reduction x0.9895)" in out, out
    assert main(["run", case, "--out", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert REDUCTION in out and "rho0 = 0.6133" in out
    assert read_csv(tmp_path / "run" / "history.csv")["rho"].size == 1


REFUSED_BY_RUN = [
    # (packing, further case lines, words of the one-line error): the YADE fixture ...
    (
        f"file = '{YADE_50}'",
        "[mesh]\nradius_factor = 0.995\n",  # a user's factor is not lowered
        [
            "radius_factor 0.995: the particle mesh's nodes lie at 1.0100 x",
            "radius_factor <= 0.9896 (or leave",
        ],
    ),
    (
        f"file = '{YADE_50}'",
        "[loading]\ntarget_density = 0.6\n",
        ["loading.target_density = 0.6", "(0.6133, 1)"],
    ),
    # ... and a generated packing (no overlap: no automatic reduction) with the coarse particle
    (
        "particles = 24",
        "[mesh]\nresolution = 'coarse'\n",
        [
            "radius_factor 0.99: the particle mesh's nodes lie at 1.0227 x",
            "radius_factor <= 0.9778, more",
        ],
    ),
]


@pytest.mark.parametrize("packing, settings, words", REFUSED_BY_RUN)
def test_check_refuses_first_what_run_refuses(tmp_path, capsys, root, packing, settings, words):
    """`run --check` exits 2 with the very line `run` exits 2 with."""
    packing = packing.replace(YADE_50, str(root / YADE_50))
    case = _case(tmp_path, f"[packing]\n{packing}\n{settings}")
    lines = []
    for args in (["run", case, "--check"], ["run", case, "--out", str(tmp_path / "run")]):
        assert main(args) == 2
        lines.append(capsys.readouterr().err.strip())
    assert lines[0] == lines[1] and len(lines[0].splitlines()) == 1, lines
    for w in words:
        assert w in lines[0], (w, lines[0])


LAMMPS_METRES = """ITEM: TIMESTEP
0
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS pp pp pp
0 0.0008
0 0.0008
0 0.0008
ITEM: ATOMS id type x y z radius
1 1 0.0002 0.0002 0.0002 0.0001
2 1 0.0006 0.0006 0.0006 0.0001
"""


def test_pack_warns_when_lengths_look_like_metres(tmp_path, capsys):
    """A LAMMPS dump in metres read without --length-scale: a one-line warning naming the fix,
    the file still written (exit 0); none with --length-scale 1000."""
    dump = tmp_path / "dump.lammps"
    dump.write_text(LAMMPS_METRES)
    assert main(["pack", "--input", str(dump), "--out", str(tmp_path / "a.txt")]) == 0
    warnings = [line for line in capsys.readouterr().out.splitlines() if "WARNING" in line]
    assert len(warnings) == 1 and "look like metres" in warnings[0], warnings
    assert "--length-scale 1000" in warnings[0]
    converted = ["--length-scale", "1000", "--out", str(tmp_path / "b.txt")]
    assert main(["pack", "--input", str(dump), *converted]) == 0
    assert "WARNING" not in capsys.readouterr().out


def test_pack_generates_a_valid_file(tmp_path):
    out = tmp_path / "p.txt"
    assert (
        main(["pack", "--particles", "30", "--seed", "4", "--fraction", "0.5", "--out", str(out)])
        == 0
    )
    assert (
        main(["pack", "--input", str(out), "--scale", "0.99", "--out", str(tmp_path / "q.txt")])
        == 0
    )
    a, b = np.loadtxt(out, skiprows=1), np.loadtxt(tmp_path / "q.txt", skiprows=1)
    assert a.shape == (30, 4) and np.allclose(b[:, 3], 0.99 * a[:, 3], rtol=1e-14)


def _not_uniform(png):
    import matplotlib.image

    img = matplotlib.image.imread(png)[..., :3]
    return img.std() > 0.02 and len(np.unique(img.reshape(-1, 3), axis=0)) > 50


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, root):
    """`mpfem run` of the tiny case as a user runs it: the console script in a subprocess."""
    out = tmp_path_factory.mktemp("tiny") / "run"
    mpfem = shutil.which("mpfem", path=str(root / ".venv" / "bin")) or str(
        root / ".venv" / "bin" / "mpfem"
    )
    proc = subprocess.run(
        [mpfem, "run", str(root / TINY), "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=root,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out, proc.stdout


def test_run_writes_history_paraview_figures_and_checkpoints(tiny_run):
    out, stdout = tiny_run
    h = read_csv(out / "history.csv")
    assert h["rho"].size == 10
    assert h["rho_imposed"][-1] == pytest.approx(0.70, abs=1e-9)
    assert abs(h["rho"][-1] - 0.70) < 0.01 and h["E_p"][-1] > 0 and h["n_contacts"][-1] > 10
    assert f"step {TINY_STEPS}/{TINY_STEPS}" in stdout and "ETA" in stdout  # the progress bar
    verdict = [line for line in stdout.splitlines() if "quasi-static check" in line]
    assert len(verdict) == 1 and "quasi-static check passed" in verdict[0], verdict  # its own check
    xdmf = (out / "particles.xdmf").read_text()
    for name in ("displacement", "von_mises_MPa", "eps_p", "particle", "contact_pressure_MPa"):
        assert f'Name="{name}"' in xdmf, name
    assert (out / "particles.h5").stat().st_size > 1e5
    for png in ("particles.png", "loading_path.png"):
        assert _not_uniform(out / png), png
    steps = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert steps == [f"step{TINY_STEPS // 2:07d}", f"step{TINY_STEPS:07d}"]


def test_plot_regenerates_the_figures(tiny_run, tmp_path):
    out, _ = tiny_run
    copy = tmp_path / "copy"
    shutil.copytree(out, copy, ignore=shutil.ignore_patterns("checkpoints", "*.png"))
    assert main(["plot", str(copy)]) == 0
    for png in ("particles.png", "loading_path.png"):
        assert _not_uniform(copy / png), png
    assert main(["plot", str(tmp_path)]) == 2  # not a results folder


def test_restart_reproduces_the_uninterrupted_run(tiny_run, tmp_path, root):
    """Explicit restart from the mid-run checkpoint: identical history (bit for bit, wall time
    aside), contact history (alpha with adhesion) included."""
    out, _ = tiny_run
    half = out / "checkpoints" / f"step{TINY_STEPS // 2:07d}"
    code = main(["run", str(root / TINY), "--out", str(tmp_path), "--restart", str(half)])
    assert code == 0
    a, b = read_csv(out / "history.csv"), read_csv(tmp_path / "history.csv")
    for name in a:
        if name != "wall_time":
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    from mpi4py import MPI

    from mpfem_fenicsx.io.checkpoint import load_checkpoint

    end = f"step{TINY_STEPS:07d}"
    ca, _ = load_checkpoint(out / "checkpoints" / end, MPI.COMM_SELF)
    cb, _ = load_checkpoint(tmp_path / "checkpoints" / end, MPI.COMM_SELF)
    assert ca["solver/contact/alpha"].max() > 0.1  # adhesive memory exists and survived
    for key in (
        "solver/u",
        "solver/contact/alpha",
        "solver/contact/sigma_max",
        "solver/material/eps_p",
    ):
        np.testing.assert_array_equal(ca[key], cb[key], err_msg=key)


def test_forced_divergence_keeps_checkpoint_and_history(tmp_path, capsys, monkeypatch, root):
    """A NaN injected in the velocities after step 100 is caught by the integrator's own check:
    exit code 3, the message names the step, the checkpoint of step 90 and the history remain
    (the tiny case with a row every 15 increments, a checkpoint every 2 rows)."""
    from mpfem_fenicsx.solvers.explicit import ExplicitSolver

    advance = ExplicitSolver.advance

    def poisoned(self):
        advance(self)
        if self.step == 100:
            self.v_red.array_w[:] = np.nan

    monkeypatch.setattr(ExplicitSolver, "advance", poisoned)
    case = (root / TINY).read_text().replace("checkpoint_every = 5", "checkpoint_every = 2")
    case = case.replace("outputs = 10", f"outputs = {TINY_STEPS // 15}")
    code = main(["run", _case(tmp_path, case), "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 3, err
    assert "stopped at step 101" in err and "step0000090" in err and "--restart" in err, err
    assert (tmp_path / "run" / "checkpoints" / "step0000090" / "meta.json").is_file()
    h = read_csv(tmp_path / "run" / "history.csv")
    assert h["rho"].size == 6 and np.isfinite(h["rho"]).all()


def test_console_script_exit_code(tmp_path, root):
    proc = subprocess.run(
        [str(root / ".venv" / "bin" / "mpfem"), "run", _case(tmp_path, "[contact]\nmu = 0.1\n")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2 and "unknown key [contact] mu" in proc.stderr


@pytest.mark.mpi
def test_mpirun_two_ranks_run_and_restart(tiny_run, tmp_path, root):
    """`mpirun -n 2 mpfem run`: the serial history within 1e-5 (relative to each column family's
    magnitude), and a 2-rank restart equal to the 2-rank run bit for bit."""
    out, _ = tiny_run
    bin_ = root / ".venv" / "bin"
    half = tmp_path / "a" / "checkpoints" / f"step{TINY_STEPS // 2:07d}"
    for args in ([], ["--restart", str(half)]):
        dest = tmp_path / ("b" if args else "a")
        proc = subprocess.run(
            [
                str(bin_ / "mpirun"),
                "-n",
                "2",
                str(bin_ / "mpfem"),
                "run",
                str(root / TINY),
                "--out",
                str(dest),
                *args,
            ],
            capture_output=True,
            text=True,
            cwd=root,
            timeout=900,
        )
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        assert proc.stdout.count(f"step {TINY_STEPS}/{TINY_STEPS}") == 1  # progress on rank 0 only
    serial, a, b = (read_csv(p / "history.csv") for p in (out, tmp_path / "a", tmp_path / "b"))
    for name in serial:
        if name == "wall_time":
            continue
        if np.isnan(serial[name]).all():  # a column this solver does not fill (implicit-only)
            assert np.isnan(a[name]).all() and np.isnan(b[name]).all(), name
            continue
        family = name.rstrip("0123456789_")
        scale = (
            max(np.nanmax(np.abs(serial[k])) for k in serial if k.rstrip("0123456789_") == family)
            + 1e-30
        )
        # a ratio is compared where its denominator is above round-off: at rest (the first row,
        # energies of 1e-32 mJ) E_c / E_int is a ratio of summation noise (E_c, E_int are compared
        # as such)
        rows = (
            serial["E_int"] > 1e-12 * np.nanmax(serial["E_int"])
            if name == "E_c_over_E_int"
            else slice(None)
        )
        assert np.nanmax(np.abs(serial[name][rows] - a[name][rows])) <= 1e-5 * scale, name
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    # a checkpoint of 2 ranks is refused by a serial restart, with the command to use
    from mpfem_fenicsx.cli.main import main as mpfem

    assert (
        mpfem(
            [
                "run",
                str(root / TINY),
                "--out",
                str(tmp_path / "c"),
                "--restart",
                str(tmp_path / "a"),
            ]
        )
        == 2
    )


@pytest.mark.mpi
def test_mpirun_three_ranks_give_the_serial_history(tiny_run, tmp_path, root):
    """`mpirun -n 3 mpfem run` (oversubscribed on 2 cores; whole particles per rank, each rank
    holding only its particles' neighbours): the same contact count at every output as the
    serial run, and every column within 1e-5 of its family's magnitude."""
    out, _ = tiny_run
    bin_ = root / ".venv" / "bin"
    proc = subprocess.run(
        [str(bin_ / "mpirun"), "-n", "3", str(bin_ / "mpfem"), "run", str(root / TINY)]
        + ["--out", str(tmp_path / "three")],
        capture_output=True,
        text=True,
        cwd=root,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    serial, three = (read_csv(p / "history.csv") for p in (out, tmp_path / "three"))
    np.testing.assert_array_equal(serial["n_contacts"], three["n_contacts"])
    for name in ("rho", "sigma_m", "sigma11", "sigma22", "sigma33", "E_p", "E_int"):
        scale = np.nanmax(np.abs(serial[name])) + 1e-30
        assert np.nanmax(np.abs(serial[name] - three[name])) <= 1e-5 * scale, name


def test_case_file_and_case_object_refuse_the_same_values(tmp_path):
    """A range is defined once (the case section's / ElastoPlastic field): every value a case file
    refuses as out of range, the case object refuses too, with the same words; its default
    passes."""
    from mpfem_fenicsx.case import SECTIONS
    from mpfem_fenicsx.cli.casefile import CaseError, to_case

    probed = 0
    for key in SCHEMA:
        if key.section == "control" or key.kind not in (int, float):
            continue
        for value in just_outside(key.range):
            with pytest.raises(CaseError, match="out of range"):
                key.check(value, "case")
            with pytest.raises(
                ValueError,
                match=rf"{key.name} = .* is out of range: must be "
                rf"{key.allowed()}",
            ):
                SECTIONS[key.section](**{key.name: value})
            probed += 1
        if key.default is not None:
            assert to_case({(key.section, key.name): key.check(key.default, "case")}, "out")
    assert probed >= 30, probed
