"""Issue 14 items 5, 6, 9, 10: every bad input listed gets one clear line (no traceback), the
user's own rewards come in through `plugins:` / `--import`, the SB3 adapter sits beside
make_vec."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from madsim.cli import main

HOWTO = Path(__file__).resolve().parents[2] / "docs" / "howto.md"


def _fails_with_one_line(capsys, argv, *needles) -> str:
    try:
        status = main(argv)
    except SystemExit as exc:           # argparse
        status = exc.code
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert status == 2, (argv, status, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.mark.parametrize("argv, needles", [
    (["run", "--seed", "-1"], ["--seed", ">= 0"]),
    (["run", "--episodes", "0"], ["--episodes", "at least 1"]),
    (["run", "--max-steps", "x"], ["--max-steps", "whole number"]),
    (["run", "--port", "0"], ["--port", "1..65535"]),
    (["drive", "--port", "70000"], ["--port", "1..65535"]),
    (["serve", "--port", "99999"], ["--port", "1..65535"]),
    (["run", "no-such-scenario.yml"], ["no-such-scenario.yml"]),
    (["run", "--driver", "nope.zip"], ["--driver", "does not exist"]),
])
def test_bad_command_line_gets_one_line(capsys, argv, needles):
    _fails_with_one_line(capsys, argv, *needles)


def test_bad_scenario_files_get_one_line(tmp_path, capsys):
    empty = tmp_path / "empty.yml"
    empty.write_text("# nothing yet\n")
    _fails_with_one_line(capsys, ["config", "check", str(empty)], "empty")
    _fails_with_one_line(capsys, ["run", str(empty)], "empty")
    off_road = tmp_path / "off.yml"
    off_road.write_text("agents:\n  - {name: d, initial_trackpos: [5, 6]}\n")
    _fails_with_one_line(capsys, ["config", "check", str(off_road)], "initial_trackpos", "[-1, 1]")
    parked = tmp_path / "parked.yml"
    parked.write_text("traffic:\n  - {behaviour: Parked, initial_trackpos: [-1.5, -0.5]}\n")
    _fails_with_one_line(capsys, ["config", "check", str(parked)], "traffic[0].initial_trackpos")


def test_drive_without_a_server_says_so_and_gives_up(capsys):
    from udp import free_ports

    start = time.monotonic()
    line = _fails_with_one_line(capsys, ["drive", "--port", str(free_ports(1)), "--wait", "1"],
                                "no SCR server answered", "madsim serve")
    assert time.monotonic() - start < 5.0, line


def test_run_render_without_a_display_says_so(capsys, monkeypatch):
    pytest.importorskip("pygame")
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER"):
        monkeypatch.delenv(var, raising=False)
    _fails_with_one_line(capsys, ["run", "--render"], "needs a display", "--video")


@pytest.mark.xdist_group("timing")       # a wall-clock budget: beside tests/cli/test_interrupts.py's
@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed")
def test_run_render_in_a_window_stops_on_sigterm(tmp_path):
    """With a (virtual) display the window opens; SIGTERM ends the run, not just the drawing."""
    pytest.importorskip("pygame")
    # the same run for a few steps first: a fresh clone compiles its kernels in the first run, and a
    # signal waits for a compile to finish (numba holds the interpreter); the timed run loads them
    warm = subprocess.run(["xvfb-run", "-a", sys.executable, "-m", "madsim.cli", "run", "--render", "--quiet",
                           "--max-steps", "20"], cwd=tmp_path, capture_output=True, text=True, timeout=240)
    assert warm.returncode == 0, warm.stderr
    proc = subprocess.Popen(["xvfb-run", "-a", sys.executable, "-m", "madsim.cli", "run", "--render", "--quiet",
                             "--episodes", "3"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    time.sleep(8.0)
    assert proc.poll() is None, proc.stderr.read()
    py = subprocess.run(["pgrep", "-s", str(proc.pid), "-f", "madsim.cli run"], capture_output=True, text=True)
    pids = [int(p) for p in py.stdout.split() if int(p) != proc.pid]
    assert pids, "the run process was not found"
    os.kill(pids[-1], signal.SIGTERM)
    t0 = time.monotonic()
    out, err = proc.communicate(timeout=30)
    assert time.monotonic() - t0 < 2.0
    assert "interrupted by SIGTERM" in err and "ended by" not in out


@pytest.fixture
def registries_restored():
    """The plugin's registrations must not leak into later tests (e.g. the generated docs)."""
    from madsim.agents.dones import DONES
    from madsim.agents.rewards import REWARDS

    saved = [(d, dict(d)) for d in (REWARDS, DONES)]
    yield
    for registry, before in saved:
        registry.clear()
        registry.update(before)
    for name in [m for m in sys.modules if m.startswith("madsim_plugin_")]:
        del sys.modules[name]


def test_plugins_bring_the_users_reward_and_done(tmp_path, capsys, registries_restored):
    """docs/howto.md's StayCentred and TooSlow, saved as my_rewards.py beside the scenario."""
    import re

    code = "\n".join(re.findall(r"```python\n(.*?)```", HOWTO.read_text(), re.S))
    (tmp_path / "my_rewards.py").write_text(code)
    body = ("server: {max_steps: 50}\nagents:\n  - name: d\n    rewards:\n      Progress2: {scale: 1.0}\n"
            "      StayCentred: {scale: 0.2, tolerance: 0.3}\n    dones: [TimeOut, TooSlow]\n")
    plain = tmp_path / "plain.yml"
    plain.write_text(body)
    with_plugins = tmp_path / "sub" / "with_plugins.yml"
    with_plugins.parent.mkdir()
    with_plugins.write_text("plugins: [../my_rewards.py]\n" + body)
    # without the plugin the reward is unknown, and the error says how to bring it in
    if "StayCentred" not in __import__("madsim.agents.rewards", fromlist=["REWARDS"]).REWARDS:
        _fails_with_one_line(capsys, ["config", "check", str(plain)], "StayCentred", "plugins")
    assert main(["config", "check", str(with_plugins)]) == 0
    assert main(["config", "check", "--import", str(tmp_path / "my_rewards.py"), str(plain)]) == 0
    assert "StayCentred" in capsys.readouterr().out
    _fails_with_one_line(capsys, ["config", "check", "--import", "no_such_module_xyz", str(plain)],
                         "no_such_module_xyz")


def test_the_sb3_adapter_sits_beside_make_vec():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import VecEnv

    import madsim

    venv = madsim.to_sb3(madsim.make_vec({"server": {"max_steps": 20}}, num_envs=2))
    try:
        assert isinstance(venv, VecEnv) and venv.num_envs == 2
        obs = venv.reset()
        assert obs.shape == (2,) + venv.observation_space.shape
        obs, rewards, dones, infos = venv.step([venv.action_space.sample() for _ in range(2)])
        assert rewards.shape == (2,) and isinstance(infos, list) and len(infos) == 2
    finally:
        venv.close()
