"""The parameter-sharing snippet of docs/scaling.md (SB3 + SuperSuit, no Ray) runs as written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "scaling.md"


def _snippet() -> str:
    text = DOC.read_text()
    m = re.search(r"<!-- sb3-snippet -->\s*```python\n(.*?)```", text, re.S)
    assert m, "docs/scaling.md lost its <!-- sb3-snippet --> block"
    return m.group(1)


def test_sb3_parameter_sharing_snippet_runs(tmp_path):
    code = _snippet()
    assert "sb3_vec_env" in code and "import ray" not in code
    r = subprocess.run([sys.executable, "-c", code + "\nprint('num_envs', vec.num_envs)\n"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "num_envs 4" in r.stdout  # 2 copies x 2 robots share one policy
    assert (tmp_path / "runs" / "sb3_shared" / "robot_ppo.zip").is_file()
