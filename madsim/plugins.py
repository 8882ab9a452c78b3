"""The user's own code for a scenario: modules that register rewards, dones or traffic behaviours.

A scenario lists them under `plugins:` (or the CLI takes `--import`); each entry is a module
name (`my_project.rewards`) or the path of a Python file (`my_rewards.py`, relative to the
config file's folder, then to the current folder). They are imported before the config is
validated, so the names they register can be used in it. Importing twice does nothing more:
a file is loaded once per process under the module name `madsim_plugin_<stem>`.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from pathlib import Path

__all__ = ["PluginError", "import_plugins", "resolve_plugin"]


class PluginError(ValueError):
    """A plugin could not be found or failed while importing (one line, names the plugin)."""


def _is_file_entry(entry: str) -> bool:
    return entry.endswith(".py") or "/" in entry or os.sep in entry


def resolve_plugin(entry: str, base: Path | None = None) -> str:
    """The entry as it is imported: an absolute path for a file entry found relative to
    `base` (a config's folder) or the current folder, else the entry itself."""
    if not _is_file_entry(entry) or os.path.isabs(entry):
        return entry
    for folder in ([base] if base is not None else []) + [Path.cwd()]:
        candidate = (folder / entry).resolve()
        if candidate.is_file():
            return str(candidate)
    return entry


def _import_file(path: Path):
    name = f"madsim_plugin_{path.stem}"
    loaded = sys.modules.get(name)
    if loaded is not None and getattr(loaded, "__file__", None) == str(path):
        return loaded
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def import_plugins(entries, base: Path | None = None) -> list:
    """Import every entry (module names or .py paths); returns the modules. PluginError (one
    line) for a plugin that is missing or raises while importing."""
    modules = []
    for entry in entries:
        entry = str(entry)
        target = resolve_plugin(entry, base)
        try:
            if _is_file_entry(target):
                path = Path(target)
                if not path.is_file():
                    raise PluginError(f"plugin {entry!r}: no such file (looked relative to "
                                      f"{'the config file and ' if base else ''}the current folder)")
                modules.append(_import_file(path))
            else:
                try:
                    modules.append(importlib.import_module(target))
                except ModuleNotFoundError as exc:
                    if exc.name != target.split(".")[0] and exc.name != target:
                        raise
                    local = Path.cwd() / f"{target}.py"
                    if not local.is_file():
                        raise PluginError(f"plugin {entry!r}: no module named {exc.name!r} (give a module "
                                          "on the Python path or the path of a .py file)") from None
                    modules.append(_import_file(local.resolve()))
        except PluginError:
            raise
        except Exception as exc:
            raise PluginError(f"plugin {entry!r} failed while importing: {type(exc).__name__}: {exc}") from None
    return modules
