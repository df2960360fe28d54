"""docs/python.md's session, run as written (in a temporary directory, from the checkout)."""

import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_session_in_the_docs_runs(tmp_path):
    text = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "docs/python.md has a Python block"
    code = blocks[0].replace('"scenes/', f'"{ROOT}/scenes/')
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(code, "docs/python.md", "exec"), {})
    finally:
        os.chdir(cwd)
    assert (tmp_path / "cornell.exr").exists()
