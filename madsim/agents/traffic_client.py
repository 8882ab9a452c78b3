"""`madsim traffic`: traffic behaviours driving cars of any scr_server over UDP.

The same behaviour objects as in-process (madsim.agents.traffic) drive K cars of a running
server (madsim serve or a TORCS race with scr_server robots), car k on port P + k, each with
its own ScrClient, behaviour object, thread and generator `behaviour_rng(seed, k)`. The
clients ask for SCR's default rangefinder angles, which the behaviours assume.

    madsim traffic --port 3001 --behaviour ConstVel --param target_speed=12 --param lane=-0.5 --count 2

A race restart makes the client identify again and start the behaviour afresh (its generator
continues); a shutdown ends it.
"""

from __future__ import annotations

import argparse
import difflib
import inspect
import sys
import threading
from collections.abc import Callable, Mapping

import numpy as np
import yaml

from madsim.agents.traffic import BEHAVIOURS, TrafficBehaviour
from madsim.net.client import RunResult, ScrClient

__all__ = ["behaviour_rng", "build_behaviour", "cmd_traffic", "drive_car",
           "parse_params", "run_traffic"]

_BASE_ARGS = ("collision_time_window", "min_safe_dist", "car")


def behaviour_rng(seed: int, k: int) -> np.random.Generator:
    """The generator of traffic car k of a run seeded `seed` (in-process tests use it too)."""
    return np.random.default_rng([int(seed), int(k)])


def parse_params(items) -> dict:
    """['k=v', ...] -> {k: v}, values read as YAML (12.5, [-0.6, 0.6], ...)."""
    out = {}
    for item in items or ():
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--param {item!r}: expected NAME=VALUE")
        try:
            out[key] = yaml.safe_load(text)
        except yaml.YAMLError:
            raise ValueError(f"--param {item!r}: {text!r} is not a number or a list") from None
    return out


def build_behaviour(name: str, params: Mapping | None = None, **base) -> TrafficBehaviour:
    """A registered behaviour by name with its parameters checked against its constructor
    (unknown names and keys raise ValueError with the nearest valid one)."""
    cls = BEHAVIOURS.get(name)
    if cls is None:
        near = difflib.get_close_matches(name, BEHAVIOURS, n=1)
        raise ValueError(f"unknown traffic behaviour {name!r}" + (f"; did you mean {near[0]!r}?"
                         if near else "") + f" (registered: {', '.join(sorted(BEHAVIOURS))})")
    accepted = [p for p in inspect.signature(cls.__init__).parameters
                if p not in ("self", "base", "pid", *_BASE_ARGS)]
    params = dict(params or {})
    for key in params:
        if key not in accepted:
            near = difflib.get_close_matches(key, accepted, n=1)
            raise ValueError(f"{name} has no parameter {key!r}" + (f"; did you mean {near[0]!r}?"
                             if near else "") + f" (parameters: {', '.join(accepted) or 'none'})")
    try:
        return cls(**params, **base)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: {exc}") from None


def drive_car(behaviour: TrafficBehaviour, client: ScrClient, rng: np.random.Generator,
              info: dict | None = None, max_steps: int | None = None) -> RunResult:
    """Identify, then answer every state with the behaviour's controls until the server shuts
    down or `max_steps` answers were sent; a restart resets the behaviour."""
    steps = 0
    client.identify()
    behaviour.reset(rng, {} if info is None else dict(info))
    while max_steps is None or steps < max_steps:
        state = client.receive()
        if state is None:
            if client.event == "restart":
                client.identify()
                behaviour.reset(rng, {} if info is None else dict(info))
                continue
            return RunResult(client.event or "shutdown", steps)
        steer, accel, brake, gear = behaviour.act(state)
        client.send({"steer": steer, "accel": accel, "brake": brake, "gear": int(gear),
                     "clutch": 0.0, "meta": 0})
        steps += 1
    return RunResult("max_steps", steps)


def run_traffic(name: str, params: Mapping | None = None, *, host: str = "127.0.0.1",
                port: int = 3001, count: int = 1, seed: int = 0, car: str | None = None,
                track_length: float | None = None, max_steps: int | None = None,
                timeout_s: float = 1.0, identify_tries: int | None = 60,
                log: Callable[[str], None] | None = None, **base) -> list[RunResult]:
    """Drive `count` cars (ports port .. port+count-1) with behaviour `name`, one thread each;
    returns each car's RunResult and re-raises the first error of any car."""
    # imported here: the sensors module loads numba, which `madsim --help` need not wait for
    from madsim.physics.sensors import SCR_DEFAULT_ANGLES_DEG

    if count < 1:
        raise ValueError(f"--count must be >= 1, got {count}")
    log = log or (lambda msg: None)
    behaviours = [build_behaviour(name, params, car=car, **base) for _ in range(count)]
    clients = [ScrClient(host, port + k, angles_deg=SCR_DEFAULT_ANGLES_DEG, timeout_s=timeout_s,
                         identify_tries=identify_tries) for k in range(count)]
    results: list = [None] * count
    errors: list = [None] * count

    def work(k: int) -> None:
        info = {"index": k, "port": port + k, "tick_s": 0.02}
        if car is not None:
            info["car"] = car
        if track_length:
            info["track_length"] = float(track_length)
        try:
            results[k] = drive_car(behaviours[k], clients[k], behaviour_rng(seed, k), info, max_steps)
            log(f"car {k} (port {port + k}): {results[k].status} after {results[k].steps} steps")
        except Exception as exc:          # reported by the caller, after every thread ended
            errors[k] = exc

    threads = [threading.Thread(target=work, args=(k,), daemon=True, name=f"traffic-{k}")
               for k in range(count)]
    try:
        for t in threads:
            t.start()
        for t in threads:
            while t.is_alive():
                t.join(0.2)
    finally:
        for c in clients:
            c.close()
    for k, exc in enumerate(errors):
        if exc is not None:
            raise RuntimeError(f"traffic car {k} (port {port + k}): {exc}") from exc
    return results


# --- command line ----------------------------------------------------------------------------


def cmd_traffic(args) -> int:
    """Run `madsim traffic`; bad arguments raise ValueError (the CLI prints one line), a car
    that fails (no server, a timeout) is reported here with exit status 2."""
    try:
        run_traffic(args.behaviour, parse_params(args.param), host=args.host, port=args.port,
                    count=args.count, seed=args.seed, car=args.car, track_length=args.track_length,
                    max_steps=args.max_steps, collision_time_window=args.collision_time_window,
                    min_safe_dist=args.min_safe_dist,
                    log=lambda m: print(f"madsim traffic: {m}", flush=True))
    except RuntimeError as exc:
        print(f"madsim: error: {exc}", file=sys.stderr)
        return 2
    return 0
