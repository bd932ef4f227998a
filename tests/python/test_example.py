# docs/python_example.py runs as written.
import os
import subprocess
import sys


def test_python_example(tmp_path):
    script = os.path.join(os.environ.get("PM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..")),
                          "docs", "python_example.py")
    r = subprocess.run([sys.executable, script, str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "sphere:" in r.stdout and "interfaces:" in r.stdout
    assert (tmp_path / "sphere.vtu").stat().st_size > 0
    assert (tmp_path / "interfaces.vtu").stat().st_size > 0
