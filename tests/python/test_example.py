# docs/python_example.py runs as written, and what it writes is what it says.
import os
import subprocess
import sys

import numpy as np
import pytest


def test_python_example(tmp_path):
    script = os.path.join(os.environ.get("PM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..")),
                          "docs", "python_example.py")
    r = subprocess.run([sys.executable, script, str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "sphere:" in r.stdout and "interfaces:" in r.stdout, r.stdout
    meshio = pytest.importorskip("meshio")
    s = meshio.read(str(tmp_path / "sphere.vtu"))
    radius = np.linalg.norm(s.points, axis=1)
    assert s.cells[0].type == "triangle" and np.all(np.abs(radius - 4.0) < 0.1)
    t = meshio.read(str(tmp_path / "sphere_tets.vtu"))
    assert t.cells[0].type == "tetra" and np.all(t.cell_data["material"][0] == 1)
    i = meshio.read(str(tmp_path / "interfaces.vtu"))
    pairs = set(zip(i.cell_data["label_a"][0].tolist(), i.cell_data["label_b"][0].tolist()))
    assert pairs == {(0, 1), (0, 2), (1, 2)}
    if "read:" in r.stdout:  # nibabel present: origin (10, 20, 30) RAS is (-10, -20, 30) LPS
        assert "frame LPS" in r.stdout and "[-10. -20.  30.]" in r.stdout, r.stdout
