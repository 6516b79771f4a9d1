"""bench/compaction.py: the documented command prints one consistent JSON object, and
bad input exits 2 naming the option (the figures themselves live in bench/README.md)."""

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench" / "compaction.py"


def _run(*args):
    return subprocess.run(
        [sys.executable, str(BENCH), *args], capture_output=True, text=True, timeout=600
    )


def test_compaction_benchmark_prints_consistent_phases():
    out = _run(
        "--particles",
        "24",
        "--bc",
        "CLP",
        "--copies",
        "--increments",
        "20",
        "--warmup",
        "4",
        "--steps",
        "3",
    )
    assert out.returncode == 0, out.stderr[-2000:]
    d = json.loads(out.stdout.strip().splitlines()[-1])
    assert d["ranks"] == 1 and d["steps"] == 3 and d["mode"] == "short"
    assert d["particles_in_model"] > 24  # CLP copies of the particles cut by the cell faces
    assert 0 < d["free_dofs"] < d["dofs"]  # CLP: the copies' dofs are tied to the originals
    assert abs(d["s_per_step"] * d["steps"] - d["wall_s"]) <= 1e-3 * d["wall_s"] + 1e-3
    phases = d["phases_s"]
    for name in (
        "material",
        "assembly",
        "contact_search",
        "contact_forces",
        "constraints",
        "update",
    ):
        assert phases[name] > 0.0, name  # every phase ran (was timed) in the measured steps
    # the timed phases cover the step (nothing large is left untimed) and do not overlap
    assert 0.6 * d["wall_s"] <= sum(phases.values()) <= 1.02 * d["wall_s"] + 1e-3
    assert 0.5 < d["rho"] < 1.0 and d["peak_rss_mb_max"] > 0


def test_compaction_benchmark_rejects_bad_input():
    out = _run("--steps", "0")
    assert out.returncode == 2 and "--steps" in out.stderr
    out = _run("--increments", "20", "--warmup", "20")
    assert out.returncode == 2 and "--warmup" in out.stderr


def test_same_history_within_round_off(tmp_path):
    """bench/same_history.py --within: equal contact counts and rho, sigma_m within the tolerance
    of their largest value pass; another contact count or a larger difference fails."""
    from bench.same_history import main

    head = "step,rho,sigma_m,n_contacts,wall_time\n"
    rows = [(1, 0.6, 0.0, 0), (2, 0.7, 1.5, 10), (3, 0.8, 4.0, 20)]

    def write(name, d_sigma=0.0, d_contacts=0):
        path = tmp_path / name
        lines = [
            f"{s},{r},{m + (d_sigma if s == 3 else 0)},{c + d_contacts},{s}.5"
            for s, r, m, c in rows
        ]
        path.write_text(head + "\n".join(lines) + "\n")
        return str(path)

    a = write("a.csv")
    assert main([a, write("b.csv", d_sigma=4e-4), "--within", "1e-3"]) == 0
    assert main([a, write("c.csv", d_sigma=4e-2), "--within", "1e-3"]) == 1
    assert main([a, write("d.csv", d_contacts=1), "--within", "1e-3"]) == 1
    assert main([a, write("e.csv", d_sigma=4e-4)]) == 1  # bit for bit: any difference fails
