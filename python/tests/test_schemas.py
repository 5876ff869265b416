"""The JSON Schemas in `schemas/` (generated from the Rust types by `diffsoft schemas`) describe
what diffsoft writes and reads: every report in `reports/` validates against the schema its
`schema` field names, every diffsoft scene of the repository against the scene schema, the suite
against the suite schema; reports made now through the Python API validate too, and a wrong type
or an unknown key does not."""

from __future__ import annotations

import copy
import json
import os
from pathlib import Path

import jsonschema
import pytest

import diffsoft
from conftest import DATA, REPO

SCHEMAS = REPO / "schemas"
# The committed reports; DIFFSOFT_REPORTS names another directory (e.g. a fresh `diffsoft verify --out`).
REPORTS = Path(os.environ.get("DIFFSOFT_REPORTS", REPO / "reports"))
SCENE_DIRS = [REPO / "verification/scenes", DATA]


def _load(path: Path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def _schemas() -> dict[str, dict]:
    """Every schema by its name (`$id`), e.g. `diffsoft.physics/2`."""
    return {s["$id"]: s for s in map(_load, sorted(SCHEMAS.glob("*.schema.json")))}


BY_ID = _schemas()


def _validator(name: str) -> jsonschema.Draft202012Validator:
    assert name in BY_ID, f"no schema named {name!r} in schemas/ (have {sorted(BY_ID)})"
    return jsonschema.Draft202012Validator(BY_ID[name])


def _errors(doc, name: str) -> list[str]:
    return [
        f"{'/'.join(map(str, e.absolute_path)) or '<root>'}: {e.message[:300]}"
        for e in _validator(name).iter_errors(doc)
    ]


def _reports() -> list[Path]:
    return sorted(p for p in REPORTS.rglob("*.json"))


def _scenes() -> list[Path]:
    return sorted(p for d in SCENE_DIRS for p in d.glob("*.json"))


def test_every_schema_is_a_valid_draft_2020_12_schema():
    assert len(BY_ID) >= 19
    for name, schema in BY_ID.items():
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["title"] == name
        assert name.startswith("diffsoft.") and "/" in name


@pytest.mark.parametrize("path", _reports(), ids=lambda p: str(p.relative_to(REPORTS)))
def test_every_report_validates_against_its_schema(path):
    doc = _load(path)
    assert isinstance(doc, dict) and "schema" in doc, f"{path}: a report names its schema"
    errors = _errors(doc, doc["schema"])
    assert not errors, f"{path} against {doc['schema']}:\n" + "\n".join(errors[:20])


def test_the_main_jobs_reports_are_there():
    names = {p.name for p in REPORTS.glob("*.json")}
    for n in [
        "bounds.json",
        "physics.json",
        "skeleton.json",
        "actuators.json",
        "jacobians.json",
        "gradients.json",
        "tradeoff.json",
        "extremes.json",
        "cloth.json",
    ]:
        assert n in names, n
    assert list((REPORTS / "sweeps").glob("*.json"))


@pytest.mark.parametrize("path", _scenes(), ids=lambda p: p.name)
def test_every_scene_validates_against_the_scene_schema(path):
    doc = _load(path)
    assert doc["schema"] == "diffsoft.scene/1"
    errors = _errors(doc, "diffsoft.scene/1")
    assert not errors, f"{path}:\n" + "\n".join(errors)


def test_the_suite_validates_against_the_suite_schema():
    doc = _load(REPO / "verification/suite.json")
    assert not _errors(doc, doc["schema"])


def test_reports_made_now_validate():
    b = diffsoft.bounds(DATA / "beam.obj", rho=1000.0, mu=1e4, dt=0.01, empirical=True)
    assert not _errors(b, b["schema"]), _errors(b, b["schema"])
    j = diffsoft.jacobians()
    assert not _errors(j, j["schema"]), _errors(j, j["schema"])


def test_a_report_with_a_wrong_type_or_an_unknown_field_fails():
    good = diffsoft.jacobians()
    assert not _errors(good, good["schema"])
    wrong_type = copy.deepcopy(good)
    wrong_type["seed"] = "2021"
    assert any(e.startswith("seed:") for e in _errors(wrong_type, good["schema"]))
    wrong_nested = copy.deepcopy(good)
    wrong_nested["checks"][0]["entries"] = 1.5
    assert _errors(wrong_nested, good["schema"])
    extra = copy.deepcopy(good)
    extra["root_update"]["colour"] = "red"
    assert _errors(extra, good["schema"])
    missing = copy.deepcopy(good)
    del missing["verdicts"]
    assert _errors(missing, good["schema"])
    # The `schema` field must name exactly the schema (another version is another schema).
    other = copy.deepcopy(good)
    other["schema"] = other["schema"].rsplit("/", 1)[0] + "/999"
    assert _errors(other, good["schema"])


def test_a_scene_with_an_unknown_key_fails(tmp_path):
    scene = _load(DATA / "beam.json")
    assert not _errors(scene, "diffsoft.scene/1")
    for where in ("top", "body", "material"):
        bad = copy.deepcopy(scene)
        target = {"top": bad, "body": bad["bodies"][0], "material": bad["bodies"][0]["material"]}[where]
        target["colour"] = "red"
        assert _errors(bad, "diffsoft.scene/1"), where
        # ... and the reader refuses it too, naming the key.
        path = tmp_path / f"{where}.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(ValueError, match="colour"):
            diffsoft.Scene.load(path)
    wrong_type = copy.deepcopy(scene)
    wrong_type["time_step"] = "0.01"
    assert _errors(wrong_type, "diffsoft.scene/1")
