"""The README's Python example runs as written, on the shipped model."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
WEIGHTS = Path(__file__).resolve().parents[1] / "motion_env" / "weights" / "gpt.pt"


@pytest.mark.skipif(not WEIGHTS.is_file(), reason="the shipped weights are not in motion_env/weights")
def test_readme_python_block_runs(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README.md has no ```python block"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)
    assert namespace["m"].joints.shape == (200, 22, 3)
    assert namespace["info"]["joints"].shape == (22, 3)
    assert (tmp_path / "walk.npz").is_file()
    namespace["envs"].close()
