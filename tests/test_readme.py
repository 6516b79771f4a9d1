"""The README's Python example runs as printed and passes its own quasi-static check."""

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_python_example_runs(tmp_path):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) == 1, "the README shows one Python example"
    proc = subprocess.run(
        [sys.executable, "-c", blocks[0]], capture_output=True, text=True, timeout=900, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert re.search(r"^rho 0\.\d{4}, sigma_m \d+\.\d{3} MPa", proc.stdout, flags=re.M), proc.stdout
    assert "quasi-static check passed" in proc.stdout, proc.stdout[-1000:]
    assert (tmp_path / "results" / "readme" / "history.csv").is_file()
