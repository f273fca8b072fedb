"""Typed, validated loading of dataclass configurations from YAML (SI units throughout).

Every dataclass configuration in wristmark is built with :func:`from_mapping`, which rejects
unknown keys, converts lists to tuples of floats with the declared length, and reports the key
and the file in a one-line :class:`ConfigError`. Range checks live in each dataclass's
``validate()`` method, called after construction.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import yaml

from wristmark.models.config_files import CONFIG_DIR, find_config
from wristmark.models.errors import ConfigError

T = TypeVar("T")


MAX_CONFIG_BYTES = 1 << 20  # [B] largest configuration or calibration file read (1 MiB)


class YamlRefusedError(yaml.YAMLError):
    """Well-formed YAML that a wristmark file must not contain: an anchor or alias, or a key
    given twice in one mapping (line: 1-based)."""

    def __init__(self, message: str, line: int) -> None:
        super().__init__(message)
        self.message = message
        self.line = line


class NoAliasSafeLoader(yaml.SafeLoader):
    """yaml.SafeLoader that refuses anchors and aliases (configuration files never need them,
    and nested aliases let a 1 KB file expand to gigabytes: the "billion laughs") and a key given
    twice in one mapping (YAML would silently keep the last)."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            sign = "*" if isinstance(event, yaml.AliasEvent) else "&"
            raise YamlRefusedError(f"YAML anchors and aliases are not allowed ('{sign}{event.anchor}'): "
                                   "write the values out", event.start_mark.line + 1)
        return super().compose_node(parent, index)

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if isinstance(key, str | int | float | bool) and key in seen:
                raise YamlRefusedError(f"key '{key}' is given twice", key_node.start_mark.line + 1)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def check_file_size(path: str | Path, limit: int = MAX_CONFIG_BYTES, what: str = "configuration file") -> Path:
    """Raise ConfigError if ``path`` is missing or larger than ``limit`` bytes (checked before
    anything reads it); return it as a Path. A missing path named like a shipped configuration
    file is that file (:func:`wristmark.models.config_files.find_config`)."""
    p = find_config(path)
    if not p.is_file():
        raise ConfigError(f"{p}: {what} not found")
    size = p.stat().st_size
    if size > limit:
        raise ConfigError(f"{p}: {what} of {size / 1e6:.1f} MB, over the {limit / 1e6:.1f} MB limit "
                          "(not read; is it the right file?)")
    return p


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from ``path``; raise :class:`ConfigError` if missing, malformed,
    larger than MAX_CONFIG_BYTES, using anchors/aliases or a key twice (:class:`NoAliasSafeLoader`)."""
    p = check_file_size(path)
    try:
        data = yaml.load(p.read_bytes(), Loader=NoAliasSafeLoader)  # noqa: S506 - a SafeLoader
    except YamlRefusedError as e:
        raise ConfigError(f"{p}:{e.line}: {e.message}") from None
    except yaml.YAMLError as e:
        first = str(e).splitlines()[0] if str(e) else "parse error"
        raise ConfigError(f"{p}: not valid YAML ({first})") from e
    except RecursionError:
        raise ConfigError(f"{p}: not valid YAML (nested too deeply)") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: expected a mapping of keys to values, got {type(data).__name__}")
    return data


def load_section(path: str | Path, name: str) -> dict[str, Any]:
    """The YAML mapping of ``path``, or the mapping under its only key ``name`` (``robot:``,
    ``controller:``, ...): both layouts of a configuration file (``extends`` resolved)."""
    return load_layered(path, name)


EXTENDS = "extends"  # the key of a configuration file that names the file it overlays
MAX_EXTENDS_DEPTH = 16  # files in one chain of ``extends`` at most
ANY_SECTION = "*"  # _layer: the section is the file's only key, whatever its name


def _base_path(p: Path, name: str) -> Path:
    """The file ``p`` extends with ``extends: name``: ``name`` relative to ``p``'s folder (or
    absolute), else the shipped configuration file of that name (``controller.yaml``,
    ``configs/controller.yaml``); a file named like a shipped one may extend it by that name."""
    given = Path(name)
    near = given if given.is_absolute() else p.parent / given
    if near.is_file() and near.resolve() != p.resolve():
        return near
    parts = given.parts[1:] if given.parts[:1] == ("configs",) else given.parts
    shipped = CONFIG_DIR.joinpath(*parts) if parts and not given.is_absolute() else None
    if shipped is not None and shipped.is_file() and shipped.resolve() != p.resolve():
        return shipped
    if near.is_file():
        return near  # the file itself: refused as a cycle
    raise ConfigError(f"{p}: 'extends: {name}' names no file (not in {p.parent}, nor a shipped configuration)")


def _layer(p: Path, section: str | None) -> tuple[dict[str, Any], str | None]:
    """One file's own mapping (under ``section:`` if the file holds only that key) and the name
    it extends (None: it extends nothing)."""
    data = load_yaml(p)
    base = data.pop(EXTENDS, None)
    if section == ANY_SECTION:
        section = next(iter(data)) if len(data) == 1 and isinstance(next(iter(data.values())), dict) else None
    if section is not None and set(data) == {section}:
        inner = data[section] if data[section] is not None else {}
        if not isinstance(inner, dict):
            raise ConfigError(f"{p}: '{section}' must be a mapping of keys to values")
        data = dict(inner)
        if EXTENDS in data:
            if base is not None:
                raise ConfigError(f"{p}: 'extends' is given twice (at the top and under '{section}')")
            base = data.pop(EXTENDS)
    if base is not None and (not isinstance(base, str) or not base.strip()):
        raise ConfigError(f"{p}: 'extends' must name a configuration file, got {base!r}")
    return data, base


def merge_mappings(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``over`` laid on it: mappings merge key by key (recursively), anything else
    (numbers, strings, lists) in ``over`` replaces ``base``'s value."""
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge_mappings(out[k], v)
        else:
            out[k] = v
    return out


def _chain(path: str | Path, section: str | None) -> list[tuple[Path, dict[str, Any]]]:
    """Each file of ``path``'s chain of ``extends`` with its own mapping, ``path`` first."""
    p = check_file_size(path)
    chain: list[tuple[Path, dict[str, Any]]] = []
    while True:
        data, base = _layer(p, section)
        chain.append((p, data))
        if base is None:
            return chain
        nxt = _base_path(p, base)
        if nxt.resolve() in {q.resolve() for q, _ in chain}:
            names = " -> ".join(str(q) for q in [*(q for q, _ in chain), nxt])
            raise ConfigError(f"{p}: 'extends' goes round in a circle ({names})")
        if len(chain) >= MAX_EXTENDS_DEPTH:
            raise ConfigError(f"{path}: more than {MAX_EXTENDS_DEPTH} files in its chain of 'extends'")
        p = check_file_size(nxt)


def load_layered(path: str | Path, section: str | None = None,
                 normalize: Callable[[dict[str, Any], str], dict[str, Any]] | None = None) -> dict[str, Any]:
    """The configuration mapping of ``path`` with its ``extends`` chain resolved.

    A file may say ``extends: NAME`` (at the top, or under its ``section:`` key when that is its
    only key): NAME is a file relative to the file's folder, or a shipped configuration's name;
    the file's own keys are laid on that file's (resolved) mapping by :func:`merge_mappings`.
    ``normalize(mapping, file)`` brings each file's own mapping to one layout before the merge
    (e.g. a sectioned and a flat file). A missing base, a cycle or a chain of more than
    MAX_EXTENDS_DEPTH files raise a one-line ConfigError naming the file."""
    merged: dict[str, Any] = {}
    for p, data in reversed(_chain(path, section)):
        merged = merge_mappings(merged, normalize(data, str(p)) if normalize is not None else data)
    return merged


def extends_chain(path: str | Path) -> list[Path]:
    """The files ``path``'s configuration is read from: ``path``, the file it extends, and so on
    (``extends`` at the top, or under the file's only key)."""
    return [p for p, _ in _chain(path, ANY_SECTION)]


def flatten_sections(data: dict[str, Any], source: str, layout: dict[str, str],
                     sections: dict[str, str]) -> dict[str, Any]:
    """One file's mapping with its sections' keys brought to the top (a file laid out in
    sections, e.g. rig.yaml's ``loop:`` and ``bench:``, and a flat one then mean the same).

    ``layout``: each sectioned key -> the name of its section; ``sections``: each section's name
    -> what it holds. A mapping without any section is returned as it is. In one with sections,
    a sectioned key must be in its own section; other keys (e.g. ``kind``) stay at the top.
    ConfigError (one line, naming the file) for a key in another section, outside its section,
    unknown in a section, or a section that is not a mapping."""
    if not any(k in sections for k in data):
        return data
    out: dict[str, Any] = {}
    for key, value in data.items():
        if key in sections:
            continue
        if key in layout:
            raise ConfigError(f"{source}: '{key}' is outside the sections ({', '.join(sections)}): "
                              f"put it under '{layout[key]}:'")
        out[key] = value
    for name in sections:
        part = data.get(name)
        if part is None:
            continue
        if not isinstance(part, dict):
            raise ConfigError(f"{source}: '{name}' must be a mapping of keys to values")
        for key, value in part.items():
            where = layout.get(str(key))
            if where is None:
                valid = [k for k, s in layout.items() if s == name]
                raise ConfigError(f"{source}: unknown key '{name}.{key}' (valid keys: {', '.join(valid)})")
            if where != name:
                raise ConfigError(f"{source}: '{key}' belongs under '{where}:' ({sections[where]}), not '{name}:'")
            out[str(key)] = value
    return out


def sectioned(flat: dict[str, Any], layout: dict[str, str], sections: dict[str, str]) -> dict[str, Any]:
    """The flat mapping laid out in sections (the inverse of :func:`flatten_sections`): keys
    without a section first, then one mapping per section, in the order of ``sections``."""
    out = {k: v for k, v in flat.items() if k not in layout}
    for name in sections:
        out[name] = {k: v for k, v in flat.items() if layout.get(k) == name}
    return out


def save_yaml(path: str | Path, data: dict[str, Any]) -> None:
    """Write ``data`` (plain Python types) as block-style YAML."""
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False, default_flow_style=None))


def _convert(value: Any, tp: Any, key: str, source: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        non_none = [a for a in args if a is not type(None)]
        return _convert(value, non_none[0], key, source)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{source}: '{key}' must be a number, got {value!r}")
        if not math.isfinite(float(value)):
            raise ConfigError(f"{source}: '{key}' must be finite, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{source}: '{key}' must be an integer, got {value!r}")
        return int(value)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{source}: '{key}' must be true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{source}: '{key}' must be a string, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{source}: '{key}' must be a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], f"{key}[{i}]", source) for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(
                f"{source}: '{key}' must have {len(args)} entries, got {len(value)}"
            )
        return tuple(_convert(v, a, f"{key}[{i}]", source) for i, (v, a) in enumerate(zip(value, args)))
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{source}: '{key}' must be a mapping, got {value!r}")
        return from_mapping(tp, value, source, prefix=f"{key}.")  # type: ignore[arg-type]
    return value


def from_mapping(cls: type[T], data: dict[str, Any], source: str = "<config>", prefix: str = "") -> T:
    """Build dataclass ``cls`` from ``data``; unknown keys and wrong types raise ConfigError.

    Missing keys take the dataclass defaults. ``cls.validate()`` is called if it exists.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    unknown = sorted(set(data) - names)
    if unknown:
        raise ConfigError(
            f"{source}: unknown key '{prefix}{unknown[0]}' (valid keys: {', '.join(sorted(names))})"
        )
    kwargs = {k: _convert(v, hints[k], prefix + k, source) for k, v in data.items()}
    obj = cls(**kwargs)
    validate = getattr(obj, "validate", None)
    if callable(validate):
        try:
            validate()
        except ConfigError as e:
            msg = str(e)
            raise ConfigError(msg if msg.startswith(source) else f"{source}: {msg}") from None
    return obj


def to_mapping(obj: Any) -> dict[str, Any]:
    """Dataclass -> plain dict of lists/floats suitable for YAML or JSON."""
    def plain(v: Any) -> Any:
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return {f.name: plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
        if isinstance(v, tuple | list):
            return [plain(x) for x in v]
        return v
    return typing.cast(dict[str, Any], plain(obj))


def load_config(cls: type[T], path: str | Path) -> T:
    """Load dataclass ``cls`` from the YAML file at ``path`` (``extends`` resolved; validated)."""
    return from_mapping(cls, load_layered(path), str(path))
