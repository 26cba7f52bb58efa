"""`motion-env studio` on the command line: its checks come first, in one line; Ctrl-C (and
`kill`) end it with exit code 130, no traceback, no process left and the port freed."""

from __future__ import annotations

import importlib.util
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from motion_env.cli import main


def _error(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err.strip()


def test_checks_before_anything_loads(capsys, monkeypatch) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        cases = [
            (["--port", "70000"], "--port must be from 0 to 65535"),
            (["--port", str(port)], f"--port {port} is in use"),
            (["--characters", "0"], "--characters must be from 1 to 16"),
            (["--characters", "17"], "--characters must be from 1 to 16"),
            (["--text", "   "], "--text is empty"),
            (["--model", "x", "--random-model"], "either --model or --random-model"),
            (["--model", "/no/such/folder"], "no generator weights directory"),
            (["--host", "no.such.host.invalid"], "is not an address of this machine"),
        ]
        for extra, message in cases:
            assert main(["studio", "--no-browser", *extra]) == 2, extra
            err = _error(capsys)
            assert err.startswith("motion-env studio: error: ") and message in err, err


def test_without_viser_the_error_names_the_extra(capsys, monkeypatch) -> None:
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "viser" else find_spec(name, *a)
    )
    assert main(["studio", "--no-browser"]) == 2
    assert 'pip install -c constraints.txt -e ".[studio]"' in _error(capsys)


def _children(pid: int) -> list[int]:
    """Processes whose parent is `pid` (Linux /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


@pytest.mark.skipif(importlib.util.find_spec("viser") is None, reason="the studio needs viser")
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="counts child processes through /proc")
@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "kill"])
def test_ctrl_c_leaves_nothing_behind(stop: signal.Signals) -> None:
    code = "import sys; from motion_env.cli import main; sys.exit(main())"
    argv = [sys.executable, "-c", code, "studio", "--random-model", "--no-browser", "--port", "0"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        line = proc.stdout.readline()  # the URL, once the page is served
        assert line.startswith("motion-env studio: http://localhost:"), (line, proc.stderr.read())
        url = line.split()[2]
        port = int(url.rsplit(":", 1)[1])
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200
        time.sleep(1.0)
        assert _children(proc.pid) == []  # nothing that could be orphaned
        proc.send_signal(stop)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "motion-env studio: interrupted", err
    assert "played" in out and "fps" in out
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # TIME_WAIT does not count
        probe.bind(("127.0.0.1", port))  # the port is free again: a new server could listen there
