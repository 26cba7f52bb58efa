"""The README is a front page that works: its Python blocks run as written on the shipped model,
its two commands are the ones CI runs, and every link of it and of docs/ leads somewhere."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
WEIGHTS = ROOT / "motion_env" / "weights" / "gpt.pt"
MAX_LINES = 250

VENV = "python3 -m venv .venv && . .venv/bin/activate && "
INSTALL_COMMAND = VENV + "pip install -c constraints.txt -e . && motion-env generate "
TEST_COMMAND = VENV + 'pip install -c constraints.txt -e ".[dev]" && pytest -q'


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


needs_weights = pytest.mark.skipif(
    not WEIGHTS.is_file(), reason="the shipped weights are not in motion_env/weights"
)


@needs_weights
def test_readme_python_blocks_run(tmp_path, monkeypatch):
    """Every block, one after the other in one namespace, as a reader pastes them. Training is cut
    to no steps; the robot block needs the `robots` extra, the learning one the `rl` one."""
    blocks = python_blocks(README.read_text())
    assert blocks, "README.md has no ```python block"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)  # generate, step the environment
    assert namespace["m"].joints.shape == (200, 22, 3)
    assert namespace["info"]["joints"].shape == (22, 3)
    assert (tmp_path / "walk.npz").is_file()
    namespace["envs"].close()
    for block in blocks[1:]:
        if "retarget" in block and importlib.util.find_spec("mink") is None:
            continue
        if "stable_baselines3" in block:
            if importlib.util.find_spec("stable_baselines3") is None:
                continue
            assert ".learn(60_000)" in block
            block = block.replace(".learn(60_000)", ".learn(0)")  # the setup only: envs, policy
        exec(compile(block, str(README), "exec"), namespace)
    assert namespace["m"].meta["control"].startswith("1 joint targets")
    assert namespace["frame"].shape == (2, 22, 3)
    if "qpos" in namespace:
        assert namespace["qpos"].shape == (2, 36)
        assert (tmp_path / "walk_g1.npz").is_file()


def test_readme_commands_are_the_ones_ci_runs():
    """The Quickstart's two commands, word for word, and `.ci/run` runs the second one."""
    text = README.read_text()
    assert INSTALL_COMMAND in text
    assert TEST_COMMAND in text
    ci = (ROOT / ".ci" / "run").read_text()
    ci_command = next(line for line in ci.splitlines() if "pytest" in line and not line.startswith("#"))
    # CI's pip is quiet (-q); otherwise the same command after the venv is made and activated.
    assert ci_command.replace("pip install -q ", "pip install ") in TEST_COMMAND


def test_readme_is_a_front_page():
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines: move details to docs/"


def slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    found: set[str] = set()
    in_code = False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        elif not in_code and line.startswith("#"):
            base = slug(line.lstrip("#"))
            name, k = base, 0
            while name in found:
                k += 1
                name = f"{base}-{k}"
            found.add(name)
    return found


DOCUMENTS = [README, ROOT / "motion_env" / "weights" / "MODEL_CARD.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_lead_somewhere(document: Path):
    """Every relative link (and its #anchor) of the README, the model card and docs/ exists."""
    text = re.sub(r"```.*?```", "", document.read_text(), flags=re.S)
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        path = (document.parent / file).resolve() if file else document
        if not path.exists():
            broken.append(f"{target}: no such file")
        elif anchor and path.suffix == ".md" and anchor not in anchors(path):
            broken.append(f"{target}: no such heading")
    assert not broken, f"{document.name}: " + "; ".join(broken)
