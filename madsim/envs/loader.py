"""The strict loader: a YAML scenario file (or a mapping) -> a validated `ScenarioConfig`.

Reads madsim's format directly and MADRaS's own files through `madsim.envs.madras_format`
(recognised by their keys); refuses unknown keys with the nearest valid one; resolves relative
track and car paths against the file's folder; reports every fault as a `ConfigError` naming
the file and the dotted key path as written in it. Also the way back: `config_to_dict` and
the `madsim config show | check` reports.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import os
import types
import warnings
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any, Union, get_args, get_origin, get_type_hints

import yaml

from madsim.envs.madras_format import MadrasTranslation, looks_madras
from madsim.envs.schema import SECTIONS, ScenarioConfig, StageConfig, TrafficConfig, generated_track_args
from madsim.envs.spaces import observation_size
from madsim.envs.validation import (
    ConfigError,
    ConfigWarning,
    as_number,
    as_pair,
    fail,
    frozen_map,
    join_key,
    unknown_name,
)
from madsim.plugins import PluginError, import_plugins, resolve_plugin

__all__ = ["check_config", "config_to_dict", "load_config", "show_config"]

_HINTS: dict[type, dict] = {}


def _hints(cls) -> dict:
    if cls not in _HINTS:
        _HINTS[cls] = get_type_hints(cls)
    return _HINTS[cls]


def _convert(tp, value, key: str):
    """`value` read from YAML as type `tp` (an annotation of the schema)."""
    origin, args = get_origin(tp), get_args(tp)
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _convert(inner, value, key)
    if tp is Any:
        return value
    if tp is bool:
        if not isinstance(value, bool):
            fail(key, "expected true or false", value)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            fail(key, "expected a whole number", value)
        return value
    if tp is float:
        return as_number(value, key)
    if tp is str:
        if not isinstance(value, str):
            fail(key, "expected a string", value)
        return value
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            if isinstance(value, str) and args[0] is str:
                value = [value]                          # "tracks: forza" means [forza]
            if not isinstance(value, (list, tuple)):
                fail(key, "expected a list", value)
            return tuple(_convert(args[0], v, join_key(key, i)) for i, v in enumerate(value))
        if len(args) == 2 and isinstance(value, Mapping):
            value = as_pair(value, key, ordered=False)     # {low: .., high: ..}
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            fail(key, f"expected a list of {len(args)} values", value)
        return tuple(_convert(a, v, join_key(key, i)) for i, (a, v) in enumerate(zip(args, value)))
    if origin in (collections.abc.Mapping, dict) or tp is Mapping:
        if not isinstance(value, Mapping):
            fail(key, "expected a mapping", value)
        inner = args[1] if args else Any
        return frozen_map({str(k): _convert(inner, v, join_key(key, str(k)))
                            for k, v in value.items()})
    if dataclasses.is_dataclass(tp):
        return _build(tp, value, key)
    raise TypeError(f"schema type {tp!r} not handled")        # a bug in this module


def _build(cls, data, key: str):
    """A schema dataclass from a YAML mapping: unknown keys are refused with the nearest
    valid one; TrafficConfig puts them into its behaviour params."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        fail(key or None, f"expected a mapping of {cls.__name__} keys", data)
    known = {f.name: f for f in fields(cls) if f.name != "params"}
    aliases = getattr(cls, "aliases", {})
    kwargs: dict[str, Any] = {}
    params: dict[str, Any] = {}
    for raw_key, value in data.items():
        name = aliases.get(str(raw_key), str(raw_key))
        sub = join_key(key, str(raw_key))
        if name not in known:
            if cls is TrafficConfig:
                params[name] = value
                continue
            raise unknown_name("key", raw_key, [*known, *aliases], sub)
        if name in kwargs:
            fail(sub, f"given twice (also as {name!r})", value)
        convert = known[name].metadata.get("convert")
        kwargs[name] = convert(value, sub) if convert else _convert(_hints(cls)[name], value, sub)
    if params:
        kwargs["params"] = params
    missing = [f.name for f in fields(cls) if f.name not in kwargs
               and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    if missing:
        fail(key or None, f"missing required key {missing[0]!r}")
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise exc.under(key) from None


def _is_path(entry: str) -> bool:
    return "/" in entry or os.sep in entry or entry.endswith((".xml", ".mtrack"))


def _resolve_paths(cfg: ScenarioConfig, base: Path) -> ScenarioConfig:
    """Relative track and car paths in a file are relative to the file's folder."""
    def fix(entry):
        if entry is None or not _is_path(entry) or os.path.isabs(entry):
            return entry
        return str((base / entry).resolve())

    def fix_all(entries):
        return None if entries is None else tuple(fix(e) for e in entries)

    server = dataclasses.replace(cfg.server, tracks=fix_all(cfg.server.tracks),
                                 cars=fix_all(cfg.server.cars),
                                 traffic_car=fix(cfg.server.traffic_car))
    agents = tuple(dataclasses.replace(a, car=fix(a.car)) for a in cfg.agents)
    traffic = tuple(dataclasses.replace(t, car=fix(t.car)) for t in cfg.traffic)
    curriculum = cfg.curriculum
    if curriculum is not None:
        stages = tuple(dataclasses.replace(
            s, tracks=fix_all(s.tracks), cars=fix_all(s.cars),
            traffic=None if s.traffic is None else tuple(
                dataclasses.replace(t, car=fix(t.car)) for t in s.traffic))
            for s in curriculum.stages)
        curriculum = dataclasses.replace(curriculum, stages=stages)
    plugins = tuple(resolve_plugin(p, base) for p in cfg.plugins)
    return dataclasses.replace(cfg, server=server, agents=agents, traffic=traffic,
                               curriculum=curriculum, plugins=plugins)


def _read_yaml(path: Path) -> Any:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read the file: {exc.strerror}", file=str(path)) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"not valid YAML: {problem}", key=where, file=str(path)) from None


def load_config(source: str | os.PathLike | Mapping | None = None, *,
                communications: str | os.PathLike | Mapping | None = None) -> ScenarioConfig:
    """A validated ScenarioConfig from a YAML file path, a mapping, or None (all defaults).

    MADRaS files are recognised by their keys. For a MADRaS devel file with `agents`, the
    `communications` file (path or mapping) defaults to a `communications.yml` next to it, as
    MADRaS reads it. TORCS-only keys raise a ConfigWarning; every fault a ConfigError.
    """
    file = None
    if source is None:
        raw: Any = {}
    elif isinstance(source, Mapping):
        raw = source
    else:
        path = Path(source)
        file = str(path)
        raw = _read_yaml(path)
    if raw is None and file is not None:
        raise ConfigError("the file is empty: a scenario needs at least one section (server, agents, "
                          "traffic; see `madsim config show` of a shipped example), or give no file for "
                          "the defaults", file=file)
    raw = {} if raw is None else raw
    if not isinstance(raw, Mapping):
        raise ConfigError("a scenario file must be a mapping of sections", value=raw, file=file)
    _import_plugins(raw, file)
    comms_file = None
    try:
        if looks_madras(raw):
            comms = communications
            if comms is None and file is not None and "agents" in raw:
                sibling = Path(file).with_name("communications.yml")
                comms = sibling if sibling.is_file() else None
            if comms is not None and not isinstance(comms, Mapping):
                comms_file = str(comms)
                comms = _read_yaml(Path(comms))
                if comms is not None and not isinstance(comms, Mapping):
                    raise ConfigError("expected a mapping of receiver agents", file=comms_file)
            madras = MadrasTranslation(comms_file)
            ours = madras.translate(raw, comms)
            try:
                cfg = _build(ScenarioConfig, ours, "")
            except ConfigError as exc:
                if madras.from_comms(exc.key):
                    exc.file = comms_file
                exc.key = madras.source_key(exc.key)
                exc.hint = madras.source_hint(exc.hint)
                raise
            _warn_madras(madras, file)
        else:
            if communications is not None:
                raise ConfigError("a communications file goes with MADRaS files; in madsim's "
                                  "format give each agent a `communication:` entry")
            for k in raw:
                if k not in SECTIONS:
                    raise unknown_name("section", k, SECTIONS, str(k))
            cfg = _build(ScenarioConfig, raw, "")
    except ConfigError as exc:
        if exc.file is None:
            exc.file = file
        raise exc from None
    if file is not None:
        cfg = _resolve_paths(cfg, Path(file).resolve().parent)
    return cfg


def _import_plugins(raw: Mapping, file: str | None) -> None:
    """Import the `plugins:` modules before validation, so the names they register are known."""
    entries = raw.get("plugins") if "plugins" in raw else None
    if entries is None:
        return
    if isinstance(entries, str) or not isinstance(entries, (list, tuple)):
        raise ConfigError("expected a list of module names or .py paths", key="plugins", value=entries,
                          file=file)
    try:
        import_plugins(entries, Path(file).resolve().parent if file else None)
    except PluginError as exc:
        raise ConfigError(str(exc), key="plugins", file=file) from None


def _warn_madras(madras, file: str | None) -> None:
    where = f"{file}: " if file else ""
    if madras.ignored:
        warnings.warn(f"{where}MADRaS keys without effect in madsim (TORCS, client or unused "
                      f"settings), accepted and ignored: {', '.join(madras.ignored)}",
                      ConfigWarning, stacklevel=3)
    for note in madras.notes:
        warnings.warn(where + note, ConfigWarning, stacklevel=3)


def _plain(obj) -> Any:
    if isinstance(obj, TrafficConfig):
        out = {f.name: _plain(getattr(obj, f.name)) for f in fields(obj) if f.name != "params"}
        out.update(_plain(obj.params))
        return out
    if isinstance(obj, StageConfig):
        return {f.name: _plain(getattr(obj, f.name)) for f in fields(obj)
                if getattr(obj, f.name) is not None}
    if dataclasses.is_dataclass(obj):
        out = {}
        for f in fields(obj):
            value = getattr(obj, f.name)
            if f.name == "rewards":
                out[f.name] = {t.name: {"scale": t.scale, **_plain(t.params)} for t in value}
            else:
                out[f.name] = _plain(value)
        return out
    if isinstance(obj, Mapping):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (tuple, list)):
        return [_plain(v) for v in obj]
    return obj


def config_to_dict(cfg: ScenarioConfig) -> dict:
    """The fully resolved config (every default filled in) as plain YAML-able data in madsim's
    format; `load_config(config_to_dict(cfg)) == cfg`."""
    return _plain(cfg)


def show_config(path: str | os.PathLike | Mapping) -> str:
    """YAML text of the fully resolved config (for `madsim config show`)."""
    return yaml.safe_dump(config_to_dict(load_config(path)), sort_keys=False,
                          default_flow_style=None, width=100)


def check_config(path: str | os.PathLike | Mapping) -> str:
    """Validate a config, including that its tracks and cars can be found; a short report of
    what it sets up (for `madsim config check`). Raises ConfigError."""
    from madsim.cars.loader import find_car
    from madsim.tracks.generate import generate_track_xml
    from madsim.tracks.library import find_track

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConfigWarning)
        cfg = load_config(path)
    file = None if isinstance(path, Mapping) else str(path)
    stages = cfg.curriculum.stages if cfg.curriculum else ()
    tracks = {t for t in cfg.server.tracks} | {t for s in stages for t in (s.tracks or ())}
    cars = ({*cfg.server.cars, cfg.server.traffic_car} | {a.car for a in cfg.agents if a.car}
            | {t.car for t in cfg.traffic if t.car} | {c for s in stages for c in (s.cars or ())})
    for track in sorted(tracks):
        args = generated_track_args(track)
        try:
            if args is None:
                find_track(track)
            else:
                generate_track_xml(**args)       # ~10 ms; some seed/size pairs cannot close
        except ValueError as exc:
            raise ConfigError(str(exc), key="tracks", value=track, file=file) from None
    for car in sorted(cars):
        try:
            find_car(car)
        except ValueError as exc:
            raise ConfigError(str(exc), key="cars", file=file) from None
    s = cfg.server
    count = (f"all {len(cfg.traffic)}" if s.traffic_count is None
             else f"{s.traffic_count[0]}-{s.traffic_count[1]}")
    lines = [f"OK {file or '<mapping>'}",
             f"  tracks ({s.order}): {', '.join(s.tracks)}",
             f"  learning cars: {', '.join(s.cars)}; traffic car: {s.traffic_car}",
             f"  traffic: {len(cfg.traffic)} entries, {count} per episode"]
    for a in cfg.agents:
        lines.append(f"  agent {a.name} ({a.car or 'drawn car'}): {a.action.space}, "
                     f"{a.observation.mode} "
                     f"({observation_size(cfg, a.name)} values), rewards "
                     f"{', '.join(t.name for t in a.rewards) or '-'}; dones {', '.join(a.dones) or '-'}")
    if cfg.curriculum:
        lines.append(f"  curriculum: {len(stages)} stages by {cfg.curriculum.unit}")
    lines += [f"  warning: {w.message}" for w in caught if issubclass(w.category, ConfigWarning)]
    return "\n".join(lines)