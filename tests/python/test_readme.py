"""The README's Python example, run as written from the repository root."""

import os
import re
import subprocess
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def test_readme_python_block_runs(tmp_path):
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    m = re.search(r"<!-- readme-python -->\s*```python\n(.*?)```", text, re.S)
    assert m, "README.md has no <!-- readme-python --> block"
    env = dict(os.environ, LGP_CACHE_DIR=str(tmp_path / "cache"))
    # From the repository root, with the package found through the block's own sys.path line
    # (the build folder is the one CTest ran from: LGP_BUILD_DIR).
    code = m.group(1).replace('"build/release/python"',
                              repr(os.path.join(os.environ.get("LGP_BUILD_DIR", "build/release"),
                                                "python")))
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "float lgp_fit(" in r.stdout or "lgp_fit" in r.stdout
    assert "B = " in r.stdout
