"""Recorded ticks of the flown loop: what the service's tick handed its pure parts (the plan,
``guidance.tick_plan.plan``; the commands through the run-time assurance,
``service.commanding.command_fleet``) and what they gave back, as JSON, exact.

``encode`` / ``decode`` turn the objects a tick passes (dataclasses, named tuples, enums, numpy
arrays, tuples, sets, dicts with integer keys, the mission) into JSON and back, every float
exactly (``json`` writes the shortest repr that reads back the same float64, and inf and NaN
as ``Infinity`` and ``NaN``; arrays go as their bytes, base64).  ``tests.record_ticks``
records them from a service flying the built-in SITL; ``tests/unit/service/
test_recorded_ticks.py`` replays them.
"""

from __future__ import annotations

import base64
import dataclasses
import enum
import gzip
import hashlib
import importlib
import json
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from gcs_ppf.mission import Mission

TICKS_DIR = Path(__file__).resolve().parent / "data" / "ticks"


def _name(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _cls(name: str) -> Any:
    module, _, qualname = name.partition(":")
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def encode(obj: Any, mission: Mission | None = None) -> Any:
    """``obj`` as JSON-able data; ``mission`` (the recording's) as a reference to it."""

    def enc(o: Any) -> Any:
        if o is None or isinstance(o, bool | str):
            return o
        if isinstance(o, enum.Enum):
            return {"__enum__": _name(type(o)), "value": o.value}
        if isinstance(o, int | float):
            return o
        if isinstance(o, np.generic):
            return {"__np__": o.dtype.str, "value": o.item()}
        if isinstance(o, np.ndarray):
            data = base64.b64encode(np.ascontiguousarray(o).tobytes()).decode("ascii")
            return {"__nd__": o.dtype.str, "shape": list(o.shape), "b64": data}
        if mission is not None and o is mission:
            return {"__mission__": None}
        if isinstance(o, BaseModel):  # the mission, a route's loiter
            return {"__model__": _name(type(o)), "value": o.model_dump(mode="json")}
        if dataclasses.is_dataclass(o) and not isinstance(o, type):
            return {"__dc__": _name(type(o)),
                    "fields": {f.name: enc(getattr(o, f.name)) for f in dataclasses.fields(o)
                               if f.init}}  # fmt: skip
        if isinstance(o, tuple) and hasattr(o, "_fields"):
            named = {k: enc(getattr(o, k)) for k in o._fields}
            return {"__nt__": _name(type(o)), "fields": named}
        if isinstance(o, tuple):
            return {"__tuple__": [enc(x) for x in o]}
        if isinstance(o, list):
            return [enc(x) for x in o]
        if isinstance(o, set | frozenset):
            return {"__set__": [enc(x) for x in sorted(o)]}
        if isinstance(o, dict):
            return {"__dict__": [[enc(k), enc(v)] for k, v in o.items()]}
        raise TypeError(f"cannot record a {type(o).__name__}")

    return enc(obj)


def decode(data: Any, mission: Mission | None = None, arrays: dict[str, Any] | None = None) -> Any:
    """What ``encode`` made, back; ``mission`` stands for its references, ``arrays`` holds
    the arrays ``write`` kept once (by digest)."""
    arrays = arrays or {}

    def dec(d: Any) -> Any:
        if isinstance(d, list):
            return [dec(x) for x in d]
        if not isinstance(d, dict):
            return d
        if "__enum__" in d:
            return _cls(d["__enum__"])(d["value"])
        if "__np__" in d:
            return np.dtype(d["__np__"]).type(d["value"])
        if "__nda__" in d:
            return dec(arrays[d["__nda__"]])
        if "__nd__" in d:
            raw = base64.b64decode(d["b64"])
            return np.frombuffer(raw, dtype=np.dtype(d["__nd__"])).reshape(d["shape"]).copy()
        if "__mission__" in d:
            assert mission is not None, "a mission reference without the mission"
            return mission
        if "__model__" in d:
            return _cls(d["__model__"]).model_validate(d["value"])
        if "__dc__" in d:
            return _cls(d["__dc__"])(**{k: dec(v) for k, v in d["fields"].items()})
        if "__nt__" in d:
            return _cls(d["__nt__"])(**{k: dec(v) for k, v in d["fields"].items()})
        if "__tuple__" in d:
            return tuple(dec(x) for x in d["__tuple__"])
        if "__set__" in d:
            return {dec(x) for x in d["__set__"]}
        if "__dict__" in d:
            return {dec(k): dec(v) for k, v in d["__dict__"]}
        return {k: dec(v) for k, v in d.items()}  # a record's own layout

    return dec(data)


SHARED_BYTES = 512
"""An array this large or larger is kept once in a recording, however often it recurs (a
tick's plan is in its plan's result, its commanding's arguments and the next plan's)."""


def _shared(data: Any, arrays: dict[str, Any]) -> Any:
    """``data`` with its large arrays moved into ``arrays``, by digest."""
    if isinstance(data, list):
        return [_shared(x, arrays) for x in data]
    if not isinstance(data, dict):
        return data
    if "__nd__" in data and len(data["b64"]) >= SHARED_BYTES:
        key = hashlib.sha1(json.dumps(data, sort_keys=True).encode()).hexdigest()
        arrays[key] = data
        return {"__nda__": key}
    return {k: _shared(v, arrays) for k, v in data.items()}


def write(path: Path, mission: Mission, ticks: list[dict[str, Any]]) -> None:
    """A recording: the mission and its ticks (each already ``encode``d), gzipped JSON."""
    arrays: dict[str, Any] = {}
    shared = _shared(ticks, arrays)
    doc = {"mission": mission.model_dump(mode="json"), "arrays": arrays, "ticks": shared}
    part = path.with_name(path.name + ".part")
    with gzip.open(part, "wt", encoding="utf-8") as f:
        json.dump(doc, f, separators=(",", ":"))
    part.replace(path)


def read(path: Path) -> tuple[Mission, list[dict[str, Any]]]:
    """A recording's mission and its ticks, decoded."""
    with gzip.open(path, "rt", encoding="utf-8") as f:
        doc = json.load(f)
    mission = Mission.model_validate(doc["mission"])
    return mission, [decode(t, mission, doc["arrays"]) for t in doc["ticks"]]
