"""scripts/import_graph.py on a small made-up package, then on motion_env itself."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "import_graph.py"


def _script():
    spec = importlib.util.spec_from_file_location("import_graph", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module


def _package(root: Path, files: dict[str, str]) -> Path:
    for name, text in {"__init__.py": "", **files}.items():
        path = root / "pkg" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root / "pkg"


def test_circles_at_import_time_late_ones_and_private_names(tmp_path, capsys) -> None:
    graph = _script()
    pkg = _package(
        tmp_path,
        {
            "a.py": "from pkg.b import run\n",
            "b.py": "from . import a\nfrom pkg.sub.c import _helper\n\ndef run():\n    from pkg import d\n",
            "d.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.b import run\n"
            "def go():\n    from .sub import c\n",
            "sub/__init__.py": "",
            "sub/c.py": "from ..d import go\n\ndef _helper():\n    pass\n",
        },
    )
    assert graph.main([str(pkg)]) == 1
    out = capsys.readouterr().out
    assert "1 circles at import time" in out and "circle: pkg.a <-> pkg.b" in out
    assert "1 private names" in out and "pkg/b.py:2 imports _helper from pkg.sub.c" in out
    assert graph.main([str(pkg), "--all"]) == 1
    # b -> d (in a function), d -> sub.c (in a function), sub.c -> d: one more circle; the
    # TYPE_CHECKING import d -> b is no edge.
    out = capsys.readouterr().out
    assert "2 circles counting function-level imports" in out
    assert "circle: pkg.d <-> pkg.sub.c" in out


def test_a_clean_package_passes_and_subpackage_circles_are_listed(tmp_path, capsys) -> None:
    graph = _script()
    pkg = _package(
        tmp_path,
        {"x/__init__.py": "", "x/m.py": "def f():\n    from pkg.y.n import g\n", "y/__init__.py": "",
         "y/n.py": "from pkg.x import m\n\ndef g():\n    pass\n"},
    )  # fmt: skip
    assert graph.main([str(pkg)]) == 0
    assert graph.main([str(pkg), "--packages"]) == 1
    assert "circle: x <-> y" in capsys.readouterr().out


def test_motion_env_has_no_circle_and_no_private_import(capsys) -> None:
    assert _script().main([str(SCRIPT.parents[1] / "motion_env")]) == 0, capsys.readouterr().out
