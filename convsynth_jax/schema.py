"""The one conversion from plain configuration data to typed parameters.

Every config group (``conf/<group>/``, ``loo``, ``jax_cache``, a task's settings, the synthetic
generator, the CDBN and Walk the Talk groups) has a frozen dataclass whose defaults are the only
defaults; :func:`build_params` turns a plain mapping (a YAML file's content, a composed config
group as plain containers, a dict written in a test) into that dataclass:

- keys are checked against the fields: an unknown key is a :class:`ConfigError` naming it
  (``walktalk.splice.cc``) and listing the known ones;
- values are checked against the field annotations (``int``, ``float``, ``bool``, ``str``,
  ``Optional[...]``, unions, ``tuple``/``List``/``Dict`` of those, nested dataclasses, ``Any``): a
  mistyped value is a ConfigError naming the key, the expected type and the value. Ints are
  accepted for floats (and become floats); lists become tuples for tuple fields;
- missing keys keep the defaults; a nested dataclass (or a dict of dataclasses) given partially is
  merged onto its default, so ``{"splice": {"c": 2.0}}`` changes one value and keeps the rest;
- a dataclass's ``__post_init__`` checks (ranges, choices) run as usual.

Nothing here knows Hydra: ``config.py`` hands over plain containers.
"""
from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any

from .errors import ConfigError, ConvSynthError

_MISSING = object()


@functools.lru_cache(maxsize=None)
def _hints(cls) -> dict:
    return typing.get_type_hints(cls)


def _type_name(tp) -> str:
    if typing.get_origin(tp) in (typing.Union, types.UnionType):   # Optional[bool]: "bool or None"
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if tp is type(None):
        return "None"
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _is_list(value) -> bool:
    """A list-like value (a list, a tuple, or another sequence that is not a string)."""
    return isinstance(value, Sequence) and not isinstance(value, (str, bytes))


def _fail(where: str, tp, value) -> ConfigError:
    return ConfigError(f"{where}: expected {_type_name(tp)}, got {type(value).__name__} {value!r}")


def _convert(value, tp, where: str, default=_MISSING):
    """``value`` checked against (and converted to) the annotation ``tp``; ``default``: the field's
    default, onto which a mapping given for a dataclass (or a dict of dataclasses) is merged."""
    if tp is Any or tp is object:
        return value
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None:
            if type(None) in args:
                return None
            raise _fail(where, tp, value)
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(value, arg, where, default)
            except ConfigError as e:
                errors.append(e)
        raise _fail(where, tp, value)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        if isinstance(value, tp):
            return value
        if not isinstance(value, Mapping):
            raise _fail(where, tp, value)
        base = default if isinstance(default, tp) else None
        return build_params(tp, value, where, base=base)
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise _fail(where, tp, value)
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise _fail(where, tp, value)
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise _fail(where, tp, value)
    if tp is str:
        if isinstance(value, str):
            return value
        raise _fail(where, tp, value)
    if tp is type(None):
        if value is None:
            return None
        raise _fail(where, tp, value)
    if tp is tuple or origin is tuple:
        if not _is_list(value):
            raise _fail(where, tp, value)
        if not args:   # a bare ``tuple``: nested lists become tuples too (hashable, as the field's default)
            return tuple(tuple(x) if _is_list(x) else x for x in value)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(x, args[0], f"{where}[{i}]") for i, x in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}: {value!r}")
        return tuple(_convert(x, a, f"{where}[{i}]") for i, (x, a) in enumerate(zip(args, value)))
    if tp is list or origin is list:
        if not _is_list(value):
            raise _fail(where, tp, value)
        return [_convert(x, args[0], f"{where}[{i}]") if args else x for i, x in enumerate(value)]
    if tp is dict or origin in (dict, Mapping, typing.Mapping):
        if not isinstance(value, Mapping):
            raise _fail(where, tp, value)
        kt, vt = args if args else (Any, Any)
        base = default if isinstance(default, Mapping) else {}
        out = {}
        for k, v in value.items():
            key = _convert(k, kt, f"{where} key {k!r}")
            out[key] = _convert(v, vt, f"{where}.{k}", base.get(k, _MISSING))
        if dataclasses.is_dataclass(vt):   # a dict of dataclasses given partially keeps its other entries
            out = {**{k: v for k, v in base.items() if k not in out}, **out}
        return out
    if isinstance(tp, type):
        if isinstance(value, tp):
            return value
        raise _fail(where, tp, value)
    return value   # an annotation this converter does not check (e.g. Literal): taken as given


def build_params(cls, data: Mapping | None = None, where: str | None = None, *, base=None):
    """The frozen dataclass ``cls`` from the plain mapping ``data`` (see the module docstring).

    where: the config path used in error messages (e.g. ``"walktalk"``, ``"task"``); base: an
    instance of ``cls`` whose values replace the defaults (``data`` is merged onto it)."""
    where = where or cls.__name__
    if data is None:
        data = {}
    if isinstance(data, cls):
        return data
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping of {cls.__name__} keys, got {type(data).__name__} {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(str(k) for k in data if k not in fields or not fields[k].init)
    if unknown:
        known = sorted(k for k, f in fields.items() if f.init)
        raise ConfigError(f"{where}: unknown key(s) {', '.join(f'{where}.{k}' for k in unknown)}; "
                          f"{cls.__name__} has {known}")
    hints = _hints(cls)
    kw = {}
    for name, f in fields.items():
        if not f.init:
            continue
        if base is not None:
            default = getattr(base, name)
        elif f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = _MISSING
        if name in data:
            kw[name] = _convert(data[name], hints[name], f"{where}.{name}", default)
        elif default is _MISSING:
            raise ConfigError(f"{where}: missing key {where}.{name} ({_type_name(hints[name])})")
        elif base is not None:
            kw[name] = default
    try:
        return cls(**kw)
    except ConvSynthError:
        raise
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{where}: {e}") from None
