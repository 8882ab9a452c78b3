"""`madsim-torcs`, the `torcs` stand-in: TORCS's command line, raceman files and scr_server.xml
car choice (spec/scr-protocol.md §8, §10, §12), then the launch / kill-by-pid / relaunch cycle
of MADRaS and the launch / restart cycle of gym_torcs against a real subprocess."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from udp import free_ports

from madsim.net import torcs_standin as T
from madsim.net.client import ScrClient

START_S = 180.0   # a cold numba cache compiles the race kernels for ~1 min
WAIT_S = 30.0
STANDIN = [sys.executable, "-m", "madsim.net.torcs_standin"]


def race_xml(track="madsim-oval", category="oval", drivers=(("scr_server", 0),), laps="1",
             distance=None, grid=None, race_name="Quick Race") -> str:
    """A raceman file laid out like TORCS's quickrace.xml and MADRaS' quickrace.template."""
    grid_xml = "".join(f'<attnum name="{k}" val="{v}"/>' for k, v in (grid or {}).items())
    dist = f'<attnum name="distance" unit="km" val="{distance}"/>' if distance is not None else ""
    laps_xml = f'<attnum name="laps" val="{laps}"/>' if laps is not None else ""
    drv = "".join(f'<section name="{k + 1}"><attnum name="idx" val="{idx}"/>'
                  f'<attstr name="module" val="{module}"/></section>' for k, (module, idx) in enumerate(drivers))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!DOCTYPE params SYSTEM "params.dtd">
<params name="Quick Race">
  <section name="Tracks"><attnum name="maximum number" val="1"/>
    <section name="1"><attstr name="name" val="{track}"/><attstr name="category" val="{category}"/></section>
  </section>
  <section name="Races"><section name="1"><attstr name="name" val="{race_name}"/></section></section>
  <section name="Quick Race">{dist}<attstr name="type" val="race"/>{laps_xml}
    <section name="Starting Grid">{grid_xml}</section>
  </section>
  <section name="Drivers"><attnum name="maximum number" val="40"/>
    <attstr name="focused module" val="scr_server"/>{drv}
  </section>
</params>
"""


def scr_server_xml(cars: dict[int, str]) -> str:
    robots = "".join(f'<section name="{i}"><attstr name="name" val="scr_server {i + 1}"/>'
                     f'<attstr name="car name" val="{car}"/></section>' for i, car in cars.items())
    return (f'<?xml version="1.0" encoding="UTF-8"?><params name="scr_server" type="robotdef">'
            f'<section name="Robots"><section name="index">{robots}</section></section></params>')


@pytest.fixture
def home(tmp_path, monkeypatch) -> Path:
    """A fake HOME; installed TORCS data folders hide no scr_server.xml from the tests."""
    import madsim.tracks.library as library

    monkeypatch.setattr(library, "torcs_data_dirs", lambda: [tmp_path / "no-torcs-data"])
    (tmp_path / "home").mkdir()
    return tmp_path / "home"


def write_scr_server(home: Path, cars: dict[int, str]) -> Path:
    p = home / ".torcs" / "drivers" / "scr_server" / "scr_server.xml"
    p.parent.mkdir(parents=True)
    p.write_text(scr_server_xml(cars))
    return p


def build(argv, home, env=None, tmp=None, xml=None):
    if xml is not None:
        (tmp / "race.xml").write_text(xml)
        argv = ["-r", str(tmp / "race.xml")] + argv
    return T.build(T.parse_args(argv), env or {}, home)


# --- command line and files --------------------------------------------------------------------


def test_madras_launch_line_gives_timeout_mode_pid_reply_and_torcs_port(home, tmp_path):
    write_scr_server(home, {0: "madsim-gt", 1: "madsim-sedan", 2: "madsim-buggy"})
    xml = race_xml(drivers=[("scr_server", 0), ("scr_server", 1), ("berniw", 4), ("scr_server", 2)])
    kwargs, plan, track = build(["-t", "10000000", "-nolaptime"], home, {"TORCS_PORT": "4100"}, tmp_path, xml)
    assert kwargs["mode"] == "timeout" and kwargs["timeout_ms"] == 10_000.0    # -t is in microseconds
    assert kwargs["ports"] == [4100, 4101, 4102] and kwargs["identified_reply"] == "pid"
    assert plan.cars == ["madsim-gt", "madsim-sedan", "madsim-buggy"] and kwargs["n_clients"] == 3
    assert kwargs["laps"] == 1 and kwargs["countdown_ticks"] == 49 and track.name == "madsim-oval"
    assert any("berniw" in note for note in plan.notes)


def test_scr_server_idx_sets_the_port_and_the_car_even_with_gaps(home, tmp_path):
    write_scr_server(home, {3: "madsim-gt"})
    xml = race_xml(drivers=[("scr_server", 3), ("scr_server", 0)])
    kwargs, plan, _ = build(["-p", "5000", "-noisy"], home, {}, tmp_path, xml)
    assert kwargs["ports"] == [5003, 5000] and kwargs["mode"] == "sync" and kwargs["noisy"]
    assert plan.cars[0] == "madsim-gt" and kwargs["identified_reply"] == "plain"
    # index 0 has no entry: SCR's default car, or madsim-sedan where TORCS's cars are missing
    try:
        from madsim.cars import load_car
        load_car(T.DEFAULT_CAR)
        assert plan.cars[1] == T.DEFAULT_CAR
    except ValueError:
        assert plan.cars[1] == T.FALLBACK_CAR and any(T.DEFAULT_CAR in n for n in plan.notes)


def test_gym_torcs_launch_line_without_race_file_uses_vtorcs_defaults(home):
    kwargs, plan, track = build(["-nofuel", "-nodamage", "-nolaptime", "-vision"], home)
    assert kwargs["ports"] == [3101] and kwargs["mode"] == "sync" and kwargs["identified_reply"] == "plain"
    assert kwargs["laps"] is None and kwargs["countdown_ticks"] == 0 and track.name == "madsim-road"
    opts = T.parse_args(["-nofuel", "-nodamage", "-vision"])
    assert not opts.fuel and not opts.damage and any("-vision" in n for n in opts.notes)
    assert build([], home, {"TORCS_PORT": "3001"})[0]["ports"] == [3001]   # MADRaS' GUI line
    assert build(["-identified", "plain"], home, {"TORCS_PORT": "3001"})[0]["identified_reply"] == "plain"
    # TORCS's lap-time limit: on as in TORCS, off with -nolaptime (as vtorcs)
    assert kwargs["lap_time_limit"] is False
    assert build(["-nofuel", "-nodamage"], home)[0]["lap_time_limit"] is True


def test_race_distance_sets_the_laps_as_torcs_does(home, tmp_path):
    # 4 km on the 1602.48 m oval: int(4000 / 1602.48) + 1 = 3 laps
    kwargs, _, _ = build([], home, {}, tmp_path, race_xml(distance="4", laps="9"))
    assert kwargs["laps"] == 3
    kwargs, _, _ = build([], home, {}, tmp_path, race_xml(laps=None))
    assert kwargs["laps"] == 30                                       # TORCS's default


@pytest.mark.parametrize("argv, message", [
    (["-x"], "unknown option '-x'"),
    (["-t"], "option -t needs a value"),
    (["-t", "10ms"], "option -t: '10ms' is not a valid int"),
    (["-t", "0"], "timeout must be > 0"),
    (["-identified", "maybe"], "use 'plain' or 'pid'"),
])
def test_bad_command_lines_are_refused_with_a_clear_message(argv, message):
    with pytest.raises(T.StandinError, match=re.escape(message)):
        T.parse_args(argv)


@pytest.mark.parametrize("xml, message", [
    (race_xml(drivers=[("berniw", 0)]), "section Drivers names no scr_server driver"),
    (race_xml(drivers=[("scr_server", 1), ("scr_server", 1)]), "Drivers/2: scr_server idx 1 appears twice"),
    (race_xml(drivers=[("scr_server", 10)]), "Drivers/1: 'idx' must be an integer 0..9, got 10.0"),
    (race_xml(track=""), "section Tracks/1 has no 'name' attribute"),
    (race_xml(track="no-such-track"), "no-such-track"),
])
def test_bad_race_files_are_refused_naming_file_and_section(home, tmp_path, xml, message):
    with pytest.raises(T.StandinError, match=re.escape(message)) as info:
        build([], home, {}, tmp_path, xml)
    assert str(info.value).startswith(str(tmp_path / "race.xml"))


def test_a_car_that_does_not_exist_names_scr_server_xml_and_the_robot(home, tmp_path):
    path = write_scr_server(home, {0: "car99-nothing"})
    with pytest.raises(T.StandinError, match=re.escape(f"{path}: Robots/index/0: car name 'car99-nothing'")):
        build([], home, {}, tmp_path, race_xml())


def test_race_grid_matches_the_world_grid_formula_shifted_by_the_race_values(home, tmp_path):
    from madsim.physics.tables import grid_positions
    from madsim.tracks import load_track

    track = load_track("madsim-oval")
    assert track.grid == {}               # so the race file's values are not overridden
    assert T.grid_placements(track, 4, {"rows": 2.0, "distance to start": 25.0}) is None
    s0, n0 = grid_positions(track, 4)     # the World's grid: quickrace values, 25 m to start
    pl = T.grid_placements(track, 4, {"distance to start": 40.0, "initial speed": 5.0})
    assert pl[:, 0] == pytest.approx(np.mod(s0 - 15.0, track.length))
    assert pl[:, 1] == pytest.approx(n0) and (pl[:, 2] == 5.0).all()
    pl = T.grid_placements(track, 3, {"rows": 1.0, "distance to start": 0.0})
    assert pl[:, 0] == pytest.approx(np.mod(track.length - np.array([0.0, 20.0, 40.0]), track.length))
    assert pl[:, 1] == pytest.approx(0.0, abs=1e-9)                 # one row: the middle


# --- real subprocesses ---------------------------------------------------------------------------



class Standin:
    """A `madsim-torcs` subprocess with its stdout collected by a thread."""

    def __init__(self, argv, env):
        self.proc = subprocess.Popen(STANDIN + argv, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=lambda: [self.lines.append(x.rstrip()) for x in self.proc.stdout],
                                       daemon=True)
        self.reader.start()

    def wait_line(self, pattern, timeout=START_S) -> re.Match:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for line in list(self.lines):
                if m := re.search(pattern, line):
                    return m
            if self.proc.poll() is not None and not self.reader.is_alive():
                break
            time.sleep(0.02)
        raise AssertionError(f"no line {pattern!r} in:\n" + "\n".join(self.lines))

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)


@pytest.fixture
def launch():
    started = []

    def start(argv, env):
        s = Standin(argv, env)
        started.append(s)
        return s

    yield start
    for s in started:
        s.kill()


def child_env(home: Path, **extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "TORCS_PORT"}
    env.update(HOME=str(home), TORCS_DATA=str(home / "no-torcs-data"), **extra)
    return env


def test_madras_cycle_launch_drive_kill_by_pid_relaunch(launch, tmp_path):
    home = tmp_path / "home"
    write_scr_server(home, {0: "madsim-sedan", 1: "madsim-gt"})
    race = tmp_path / "quickrace.xml"
    race.write_text(race_xml(drivers=[("scr_server", 0), ("scr_server", 1)],
                             grid={"distance to start": 0, "rows": 2}))
    base = free_ports(2)
    env = child_env(home, TORCS_PORT=str(base))
    argv = ["-t", "10000000", "-r", str(race), "-nolaptime"]      # MADRaS' line, verbatim
    for attempt in range(2):
        torcs = launch(argv, env)
        torcs.wait_line(r"waiting for 2 client")
        assert "madsim-sedan, madsim-gt" in "\n".join(torcs.lines)
        clients = [ScrClient("127.0.0.1", base + i, timeout_s=2.0, identify_tries=10, silent_tries=15)
                   for i in range(2)]
        try:
            assert [c.identify() for c in clients] == [torcs.proc.pid] * 2   # the stand-in's own pid
            first = None
            for tick in range(60):          # 49 countdown states, then racing
                states = [c.receive() for c in clients]
                first = first or states
                for c in clients:
                    c.send({"accel": 1.0, "gear": 1})
            assert states[0]["curLapTime"] > 0 > first[0]["curLapTime"]
        finally:
            for c in clients:
                c.close()
        # distance to start 0: the pole car sits on the line, the next one 10 m behind it (§7)
        behind = [(1602.48 - s["distFromStart"]) % 1602.48 for s in first]
        assert behind == pytest.approx([0.0, 10.0], abs=1e-3)
        os.kill(torcs.proc.pid, signal.SIGKILL)         # MADRaS' reset
        assert torcs.proc.wait(timeout=10) == -signal.SIGKILL   # ports free again: relaunch


def test_gym_torcs_cycle_restart_then_a_new_client_identifies(launch, tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    port = free_ports(1)
    torcs = launch(["-nofuel", "-nodamage", "-nolaptime", "-p", str(port)], child_env(home))
    torcs.wait_line(r"waiting for 1 client")
    first = ScrClient("127.0.0.1", port, timeout_s=2.0, identify_tries=10, silent_tries=15)
    try:
        assert first.identify() is None                        # plain ***identified***
        states = []
        for tick in range(30):
            states.append(first.receive())
            first.send({"accel": 1.0, "gear": 1, "meta": int(tick == 29)})
        assert first.receive() is None and first.event == "restart"
    finally:
        first.close()
    assert states[0]["curLapTime"] == 0.0                      # vtorcs: no countdown
    assert states[-1]["speedX"] > 5.0 and states[-1]["fuel"] == states[0]["fuel"]   # -nofuel
    with ScrClient("127.0.0.1", port, timeout_s=2.0, identify_tries=10, silent_tries=15) as second:
        second.identify()                                      # gym_torcs makes a new client
        again = second.receive()
    assert again["distRaced"] == 0.0 and again["speedX"] == 0.0
    torcs.wait_line(r"restart requested by the client of car 0", timeout=WAIT_S)


def test_tick_schedule_option(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    kwargs, _, _ = build(["-tick-schedule", "torcs"], home)
    assert kwargs["tick_schedule"] == "torcs"
    assert build([], home)[0]["tick_schedule"] == "fixed"
    with pytest.raises(T.StandinError, match="-tick-schedule"):
        T.parse_args(["-tick-schedule", "often"])
