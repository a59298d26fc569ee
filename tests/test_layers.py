"""The folders are layers: which package may import which, and what the pure ones may not touch.

Every module of ``gcs_ppf``, ``sitl`` and ``api`` is parsed (not imported) and each of its
imports, at any depth (inside functions and ``TYPE_CHECKING`` blocks too), is checked against
the rules below. A new module outside every layer fails too: decide where it belongs, then add
it to ``LAYERS`` (and to docs/layout.md).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

IO = frozenset(
    {
        "asyncio", "socket", "socketserver", "selectors", "ssl", "sqlite3", "http", "urllib",
        "httpx", "requests", "fastapi", "starlette", "uvicorn", "pymavlink", "mavsdk",
        "subprocess", "multiprocessing", "threading", "concurrent", "signal", "shutil",
        "tempfile", "os", "sys", "io", "time", "datetime", "logging", "random", "csv",
        "matplotlib", "tqdm", "pydantic_settings", "api", "sitl", "serial",
        "serial_asyncio",
    }
)  # fmt: skip
"""Modules a pure layer may not import: I/O, clocks, processes, the network, the database,
MAVLink's wire library, plotting, the shells (planners take time and ``dt`` as arguments)."""

CONTRACTS = ("gcs_ppf.mission", "gcs_ppf.frames", "gcs_ppf.geodesy")


@dataclass(frozen=True)
class Layer:
    """Modules under ``prefixes`` may import project modules under ``may_import`` only, and
    no third-party or standard module in ``forbidden``."""

    name: str
    prefixes: tuple[str, ...]
    may_import: tuple[str, ...]
    forbidden: frozenset[str]


LAYERS = (
    Layer("contracts", CONTRACTS, CONTRACTS, IO),
    Layer("planning", ("gcs_ppf.planning",), (*CONTRACTS, "gcs_ppf.planning"), IO),
    Layer("mavlink", ("gcs_ppf.mavlink",), (*CONTRACTS, "gcs_ppf.mavlink"), IO - {"pymavlink"}),
    Layer(
        "guidance",
        ("gcs_ppf.guidance",),
        (*CONTRACTS, "gcs_ppf.planning", "gcs_ppf.mavlink", "gcs_ppf.guidance"),
        IO,
    ),
    Layer(
        "offline",
        ("gcs_ppf.offline",),
        (*CONTRACTS, "gcs_ppf.planning", "gcs_ppf.offline"),
        frozenset(
            {
                "asyncio",
                "socket",
                "sqlite3",
                "httpx",
                "fastapi",
                "uvicorn",
                "pymavlink",
                "api",
                "sitl",
            }
        ),
    ),
    # API tokens: hashes and token files; no network, no server (service, api, cli use it)
    Layer(
        "tokens",
        ("gcs_ppf.tokens",),
        ("gcs_ppf.tokens",),
        IO - {"os"},
    ),
    Layer(
        "service",
        ("gcs_ppf.service",),
        (
            *CONTRACTS,
            "gcs_ppf.planning",
            "gcs_ppf.mavlink",
            "gcs_ppf.guidance",
            "gcs_ppf.service",
            "gcs_ppf.tokens",
            "gcs_ppf.datagrams",
        ),
        frozenset({"matplotlib", "api", "sitl"}),
    ),
    # a UDP socket read a whole backlog at a time: the service's links and the SITL's
    Layer("datagrams", ("gcs_ppf.datagrams",), ("gcs_ppf.datagrams",), frozenset({"api", "sitl"})),
    # zones from operators' files (GeoJSON, QGroundControl .plan): parsing only, pure
    Layer(
        "imports",
        ("gcs_ppf.zone_import", "gcs_ppf.plan_route"),
        (*CONTRACTS, "gcs_ppf.zone_import", "gcs_ppf.plan_route"),
        IO,
    ),
    Layer("tools", ("gcs_ppf.tools",), (*CONTRACTS, "gcs_ppf.tools"), frozenset({"api", "sitl"})),
    Layer("package", ("gcs_ppf",), (), frozenset()),  # gcs_ppf/__init__.py: numba's cache dir
    Layer("cli", ("gcs_ppf.cli",), ("gcs_ppf", "api"), frozenset({"sitl"})),
    Layer(
        "api",
        ("api",),
        (
            *CONTRACTS,
            "gcs_ppf.planning",
            "gcs_ppf.guidance",
            "gcs_ppf.service",
            "gcs_ppf.offline",
            "gcs_ppf.tokens",
            "gcs_ppf.zone_import",
            "gcs_ppf.plan_route",
            "api",
        ),
        frozenset(),
    ),
    Layer(
        "sitl",
        ("sitl",),
        (*CONTRACTS, "gcs_ppf.mavlink", "gcs_ppf.datagrams", "sitl"),
        frozenset({"api"}),
    ),
)

PROJECT = ("gcs_ppf", "sitl", "api")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(module: str) -> Layer | None:
    """The layer whose prefix matches ``module`` most closely (``gcs_ppf`` alone only for the
    package's ``__init__``)."""
    best: tuple[int, Layer] | None = None
    for layer in LAYERS:
        for p in layer.prefixes:
            exact_only = p == "gcs_ppf" or p in CONTRACTS or p == "gcs_ppf.cli"
            hit = module == p or (not exact_only and module.startswith(p + "."))
            if hit and (best is None or len(p) > best[0]):
                best = (len(p), layer)
    return best[1] if best else None


def imports(source: str, module: str, is_package: bool) -> set[str]:
    """Every module ``source`` imports, absolute; ``from pkg import name`` gives ``pkg.name``
    too, which is the module imported when ``name`` is a submodule."""
    found: set[str] = set()
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                stem = ".".join([*base, node.module] if node.module else base)
            else:
                stem = node.module or ""
            found.add(stem)
            found.update(f"{stem}.{a.name}" for a in node.names)
    return found


def _matches(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def violations(module: str, source: str, is_package: bool = False) -> list[str]:
    """What ``module`` (its source) imports against its layer's rules."""
    layer = layer_of(module)
    if layer is None:
        return [f"{module}: in no layer (add it to tests/test_layers.py LAYERS and docs/layout.md)"]
    found = []
    for name in sorted(imports(source, module, is_package)):
        top = name.split(".")[0]
        if top in PROJECT:
            if name == top or not _is_project_module(name):
                continue  # ``from gcs_ppf.x import y``: the module is gcs_ppf.x (or .x.y)
            if not any(_matches(name, allowed) for allowed in layer.may_import):
                found.append(f"{module} ({layer.name}) imports {name}")
        elif top in layer.forbidden:
            found.append(f"{module} ({layer.name}) imports {name}")
    return found


def _is_project_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def project_modules() -> list[Path]:
    return sorted(p for top in PROJECT for p in (ROOT / top).rglob("*.py"))


@pytest.mark.parametrize("path", project_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_module_imports_only_what_its_layer_may(path: Path) -> None:
    module = module_name(path)
    assert violations(module, path.read_text(), path.name == "__init__.py") == []


@pytest.mark.parametrize("path", project_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_module_opens_with_a_docstring(path: Path) -> None:
    """Each module says in its first sentence what it is for."""
    assert ast.get_docstring(ast.parse(path.read_text())), f"{path} has no module docstring"


@pytest.mark.parametrize(
    ("module", "source"),
    [
        ("gcs_ppf.planning.rollout", "import asyncio\n"),
        ("gcs_ppf.planning.scene", "def f():\n    import sqlite3\n"),
        ("gcs_ppf.planning.apf", "from gcs_ppf.service import runs\n"),
        ("gcs_ppf.planning.apf", "from gcs_ppf.offline.plan import plan_mission\n"),
        ("gcs_ppf.mission", "from gcs_ppf.planning.scene import Scene\n"),
        ("gcs_ppf.frames", "import time\n"),
        ("gcs_ppf.geodesy", "from pymavlink import mavutil\n"),
        ("gcs_ppf.guidance.online", "import socket\n"),
        ("gcs_ppf.guidance.slew", "from gcs_ppf.service.fleet import Fleet\n"),
        ("gcs_ppf.mavlink.codec", "import asyncio\n"),
        ("gcs_ppf.planning.ppf.kernel", "from ..scene import Scene\nimport httpx\n"),
        ("gcs_ppf.offline.plots", "import fastapi\n"),
        ("gcs_ppf.service.fleet", "from gcs_ppf.offline import output\n"),
        ("sitl.engine", "from gcs_ppf.guidance import online\n"),
        ("gcs_ppf.newcomer", "import json\n"),  # in no layer
    ],
)
def test_the_rules_catch_a_forbidden_import(module: str, source: str) -> None:
    assert violations(module, source) != []


def test_the_rules_allow_the_planned_direction() -> None:
    assert violations("gcs_ppf.guidance.online", "from gcs_ppf.planning import planner\n") == []
    assert violations("gcs_ppf.planning.ppf.reference", "from ..scene import Scene\n") == []
    shell = "import asyncio\nfrom gcs_ppf.guidance import slew\n"
    assert violations("gcs_ppf.service.runs", shell) == []
