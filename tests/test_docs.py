"""The user's documents stay true: the README is a short guide, every link between the documents
and every ``examples/`` file they name exists, the README's ``gcs-ppf`` commands parse, every
subcommand answers ``--help``, the examples validate, and docs/mission.md lists every field of
the mission models."""

from __future__ import annotations

import argparse
import re
import shlex
from pathlib import Path

import pytest
from pydantic import BaseModel

from gcs_ppf.cli import build_parser
from gcs_ppf.mission import (
    CylinderZone,
    Limits,
    Mission,
    Obstacle,
    Origin,
    PlannerSettings,
    PolygonZone,
    Vehicle,
    Waypoint,
    load_mission_file,
)
from tests.conftest import EXAMPLES, ROOT

README = ROOT / "README.md"
DOCUMENTS = [README, ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]
README_MAX_LINES = 300

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
EXAMPLE = re.compile(r"examples/([a-z0-9_]+\.json)")
SHELL_OPERATORS = {">", ">>", "2>", "|", "&&", ";"}
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)

# Each model's fields are listed as table rows (| `field` | …) in the section with this heading.
MISSION_SECTIONS: dict[str, type[BaseModel] | tuple[type[BaseModel], ...]] = {
    "## The document": Mission,
    "## `origin`": Origin,
    "## `limits`": Limits,
    "## `planner`": PlannerSettings,
    "## `route[]`": Waypoint,
    "## `vehicles[]`": Vehicle,
    "## `obstacles[]`": Obstacle,
    "## `zones[]`": (CylinderZone, PolygonZone),  # a table for each kind
}


def test_readme_is_a_short_guide() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES
    assert not [h for h in lines if re.match(r"#+ (Session|session) \d", h)]


@pytest.mark.parametrize("doc", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_link_and_example_exists(doc: Path) -> None:
    text = doc.read_text(encoding="utf-8")
    missing = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+://", target) or target.startswith("#"):
            continue
        path = (doc.parent / target.split("#", 1)[0]).resolve()
        if not path.exists():
            missing.append(target)
    missing += [
        f"examples/{name}" for name in EXAMPLE.findall(text) if not (EXAMPLES / name).exists()
    ]
    assert not missing, f"{doc.name}: {missing}"


def test_every_document_is_linked_from_the_readme() -> None:
    linked = {
        (README.parent / t.split("#", 1)[0]).resolve() for t in LINK.findall(README.read_text())
    }
    unlinked = [d.name for d in DOCUMENTS[1:] if d.resolve() not in linked]
    assert not unlinked


def readme_gcs_ppf_commands() -> list[list[str]]:
    """The arguments of every ``.venv/bin/gcs-ppf …`` line in the README's shell blocks."""
    out = []
    for lang, block in FENCE.findall(README.read_text(encoding="utf-8")):
        if lang != "sh":
            continue
        for line in block.splitlines():
            words = shlex.split(line, comments=True)
            if words and words[0] == ".venv/bin/gcs-ppf":
                shell = [i for i, w in enumerate(words) if w in SHELL_OPERATORS]
                out.append(words[1 : shell[0] if shell else None])  # up to `> file`, `| …`
    return out


def test_the_readme_runs_gcs_ppf() -> None:
    assert {args[0] for args in readme_gcs_ppf_commands()} >= {"plan", "sweep", "serve"}


@pytest.mark.parametrize("args", readme_gcs_ppf_commands(), ids=lambda a: " ".join(a[:2]))
def test_readme_commands_parse_and_name_files_that_exist(args: list[str]) -> None:
    build_parser().parse_args(args)  # SystemExit (a failure) on a bad option
    for word in args:
        if word.startswith(("examples/", "tests/data/")):
            assert (ROOT / word).exists(), word


def subcommands() -> list[str]:
    parser = build_parser()
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return sorted(actions[0].choices)


@pytest.mark.parametrize("command", subcommands())
def test_every_subcommand_answers_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args([command, "--help"])
    assert exit_.value.code == 0
    assert f"gcs-ppf {command}" in capsys.readouterr().out


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.json")), ids=lambda p: p.name)
def test_the_examples_validate(path: Path) -> None:
    load_mission_file(path)


def test_the_mission_reference_lists_every_field() -> None:
    text = (ROOT / "docs" / "mission.md").read_text(encoding="utf-8")
    headings = list(MISSION_SECTIONS)
    missing = []
    for k, heading in enumerate(headings):
        assert heading in text, heading
        start = text.index(heading)
        later = [text.index(h) for h in headings[k + 1 :] if text.index(h) > start]
        section = text[start : min(later, default=len(text))]
        models = MISSION_SECTIONS[heading]
        missing += [
            f"{model.__name__}.{name}"
            for model in (models if isinstance(models, tuple) else (models,))
            for name in model.model_fields
            if f"| `{name}` |" not in section
        ]
    assert not missing
