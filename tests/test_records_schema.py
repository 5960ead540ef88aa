"""results.json's contract: the TypedDicts of crosscheck.checks.records, the JSON Schema shipped
in crosscheck/schema/ and docs/results.md say the same; real `crosscheck run` outputs follow the
schema; `crosscheck report` and `crosscheck gate` refuse a file that breaks it with one line
naming the first violation and its JSON path, and exit 2."""

from __future__ import annotations

import copy
import importlib.util
import json
import math
import re
import tomllib
import types
import typing
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator

from crosscheck.checks import records as R
from crosscheck.cli import main
from crosscheck.report.inputs import is_baseline, schema_violations
from crosscheck.runtime import jsonio
from crosscheck.schema import RESULTS_SCHEMA, results_schema

ROOT = Path(__file__).resolve().parents[1]
FOURBAR = ROOT / "tests" / "data" / "fourbar_connect.xml"
# a soft engine's answers (pendulum_xy), work done on the system (the moving support), an
# engine with two models of one reference model (Example 4)
MODELS = ("pendulum_xy", "pendulum_moving_support", "double_pendulum_3d")
# record fields the runs below cannot produce: a run that does not finish (made in its own test
# below) and an engine's warning that it reset an unstable step
NOT_IN_A_CLEAN_RUN = {"failure", "engine_warnings"}
# the fields of users' MJCF files with contacts, limits, actuators, an initial state projected
# or quaternions (the model_file record's figures, the multipliers' left-out rows): the run
# above has none of those; tests/test_mjcf_unilateral.py::test_user_file_records_follow_the_schema
# makes them and holds them to the schema
NOT_IN_A_CLEAN_RUN |= {
    "contact_pairs",
    "limits",
    "states_rejected",
    "controls",
    "projection",
    "rows_left_out",
}


def _nfourbar() -> types.ModuleType:
    """examples/a02/nfourbar.py, which writes the A02 N-four-bar's MJCF file."""
    path = ROOT / "examples" / "a02" / "nfourbar.py"
    spec = importlib.util.spec_from_file_location("nfourbar", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def runs(tmp_path_factory, session_child) -> dict[str, Path]:
    """results.json of real runs with every available engine and trajectories: "clean" (the
    built-in MODELS; a user's MJCF four-bar with equality constraints, for Pinocchio's parser
    record and MuJoCo's reported trajectories; the A02 one-cell four-bar, whose reference reaches
    a flat pose, so its horizon is cut) and "faulty" (MuJoCo's slider-crank with m2 changed by
    1e-6: failing records; with the derivatives records, analytical, differenced and soft)."""
    root = tmp_path_factory.mktemp("runs")
    a02 = root / "a02_1.xml"
    a02.write_text(_nfourbar().mjcf(1))
    common = ("--states", "2", "--t-end", "1", "--no-report")
    clean = session_child.crosscheck(
        "run",
        *MODELS,
        "fourbar_connect",
        "a02_1",
        "--model-file",
        FOURBAR,
        "--model-file",
        a02,
        *common,
        "--out",
        root / "clean",
    )
    assert clean.returncode == 0, clean.stdout + clean.stderr
    faulty = session_child.crosscheck(
        "run",
        "slider_crank",
        "--perturb",
        "mujoco:m2=1e-6",
        "--derivatives",
        *common,
        "--out",
        root / "faulty",
    )
    assert faulty.returncode == 1, faulty.stdout + faulty.stderr
    return {k: root / k / "results.json" for k in ("clean", "faulty")}


@pytest.fixture(scope="module")
def clean(runs) -> dict:
    return json.loads(runs["clean"].read_text())


@pytest.fixture(scope="module")
def baseline(runs, tmp_path_factory) -> Path:
    """A baseline made from the clean run the way the lead makes one (gate --update)."""
    path = tmp_path_factory.mktemp("baseline") / "baseline.json"
    assert main(["gate", "--baseline", str(path), "--results", str(runs["clean"]), "--update"]) == 0
    return path


def _pointer(schema: dict, pointer: str):
    node = schema
    for part in pointer.removeprefix("#").strip("/").split("/"):
        if part:
            node = node[part]
    return node


# ---- real output follows the schema ---------------------------------------------------------


def test_real_runs_follow_the_schema(runs):
    """Both runs validate, and between them they hold every field the schema describes (so the
    validation is not vacuous), failing, skipped and reported records, series and matrices."""
    from crosscheck.engines.registry import available_engines

    fields, series_fields = set(), set()
    for kind, path in runs.items():
        data = json.loads(path.read_text())
        assert schema_violations(data) == [], kind
        assert set(data) == set(results_schema()["properties"]), kind  # run writes all four
        assert set(data["meta"]) == set(results_schema()["$defs"]["meta"]["properties"]), kind
        assert {r["engine"] for r in data["records"]} == {"reference", *available_engines()}
        fields |= {k for r in data["records"] for k in r}
        series_fields |= {k for s in data["series"] for k in s}
        assert data["series"] and data["agreement"], kind
    record_schema = results_schema()["$defs"]["record"]
    assert fields == set(record_schema["properties"]) - NOT_IN_A_CLEAN_RUN
    assert series_fields == set(results_schema()["$defs"]["series"]["properties"])
    faulty = json.loads(runs["faulty"].read_text())["records"]
    assert any(r["passed"] is False for r in faulty)
    clean = json.loads(runs["clean"].read_text())["records"]
    assert any(r["skipped"] and r["error"] is None for r in clean)
    assert any(r["skipped"] and "judged_tolerance" in r for r in clean)  # reported


def test_a_run_that_does_not_finish_follows_the_schema(monkeypatch):
    """The failure record (error Infinity, tolerance 0) and the engines' skips, as written."""
    import crosscheck.checks.trajectory.check as T
    from crosscheck.engines.registry import get_engine
    from reference import NumericModel, models
    from reference.integrate.driver import IntegrationError

    def underflow(*a, **k):
        raise IntegrationError("pendulum_xy: step size underflow at t = 0.31")

    monkeypatch.setattr(T, "simulate", underflow)
    nm = NumericModel(models.get("pendulum_xy"))
    records, _ = T.trajectory_records("pendulum_xy", nm, [get_engine("pinocchio")], 0.1)
    data = json.loads(jsonio.dumps({"meta": {}, "records": records}))
    (failed,) = [r for r in data["records"] if r.get("failure")]
    assert math.isinf(failed["error"]) and failed["tolerance"] == 0 and failed["passed"] is False
    assert schema_violations(data) == []
    failed["tolerance"] = 1e-8  # the rule: a failure's tolerance is 0
    assert any(".tolerance: expected 0, got 1e-08" in v for v in schema_violations(data))


def test_report_and_gate_accept_real_runs(runs, baseline, tmp_path):
    """The report renders the faulty run; the gate's own baseline validates as a baseline, the
    clean run passes the gate and the faulty one fails it (exit 1: failing records are valid
    results, not bad input)."""
    assert main(["report", "--results", str(runs["faulty"]), "--out", str(tmp_path)]) == 0
    stored = json.loads(baseline.read_text())
    assert is_baseline(stored) and schema_violations(stored) == []
    gate = ["gate", "--baseline", str(baseline), "--results"]
    assert main([*gate, str(runs["clean"])]) == 0
    assert main([*gate, str(runs["faulty"]), "--accept-new"]) == 1


def test_committed_baseline_follows_the_schema():
    """reports/baseline.json, which CI's gate loads, is a baseline whose records follow the
    record schema."""
    data = json.loads((ROOT / "reports" / "baseline.json").read_text())
    assert is_baseline(data)
    assert schema_violations(data) == []


# ---- a file that breaks the schema is refused -----------------------------------------------


def _judged(data) -> int:
    return next(i for i, r in enumerate(data["records"]) if not r["skipped"])


def _skipped(data) -> int:
    return next(
        i for i, r in enumerate(data["records"]) if r["skipped"] and "judged_tolerance" not in r
    )


def _missing_field(d):
    del d["records"][i := _judged(d)]["reason"]
    return f"$.records[{i}]: 'reason' is a required property"


def _wrong_type(d):
    d["records"][i := _judged(d)]["error"] = "0.1"
    return f'$.records[{i}].error: expected number or null, got "0.1"'


def _passed_on_a_skip(d):
    d["records"][i := _skipped(d)]["passed"] = False
    return f"$.records[{i}].passed: expected null, got false; a skipped record"


def _error_on_a_skip(d):
    d["records"][i := _skipped(d)]["error"] = 0.5
    return f"$.records[{i}].error: expected null, got 0.5; a skipped record has error null"


def _zero_tolerance(d):
    d["records"][i := _judged(d)]["tolerance"] = 0.0
    return f"$.records[{i}].tolerance: 0.0 is less than or equal to the minimum of 0"


def _undeclared_field(d):
    d["records"][i := _judged(d)]["colour"] = "red"
    return f"$.records[{i}]: Additional properties are not allowed ('colour' was unexpected)"


def _unknown_check(d):
    d["records"][i := _judged(d)]["check"] = "instant"
    return f'$.records[{i}].check: "instant" is not one of'


def _unknown_top_level_key(d):
    d["extra"] = {}
    return "$: Additional properties are not allowed ('extra' was unexpected)"


def _series_without_times(d):
    del d["series"][0]["t"]
    return "$.series[0]: 't' is a required property"


def _unknown_agreement_quantity(d):
    d["agreement"][0]["quantity"] = "energy"
    return '$.agreement[0].quantity: "energy" is not one of'


def _meta_of_a_wrong_type(d):
    d["meta"]["jobs"] = "2"
    return '$.meta.jobs: expected integer, got "2"'


# each changes a copy of the clean results and returns what the error must say
VIOLATIONS = {
    f.__name__.strip("_").replace("_", " "): f
    for f in (
        _missing_field,
        _wrong_type,
        _passed_on_a_skip,
        _error_on_a_skip,
        _zero_tolerance,
        _undeclared_field,
        _unknown_check,
        _unknown_top_level_key,
        _series_without_times,
        _unknown_agreement_quantity,
        _meta_of_a_wrong_type,
    )
}


@pytest.mark.parametrize("command", ["report", "gate"])
@pytest.mark.parametrize("violation", list(VIOLATIONS))
def test_a_file_that_breaks_the_schema_is_refused(
    clean, baseline, tmp_path, capsys, violation, command
):
    data = copy.deepcopy(clean)
    expected = VIOLATIONS[violation](data)
    bad = tmp_path / "results.json"
    bad.write_text(json.dumps(data))
    site = tmp_path / "site"
    argv = {
        "report": ["report", "--results", str(bad), "--out", str(site)],
        "gate": ["gate", "--baseline", str(baseline), "--results", str(bad)],
    }[command]
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == "", out + err
    assert err.startswith("crosscheck: error:") and err.count("\n") == 1, err
    assert f"results file {str(bad)!r}: {expected}" in err, err
    assert "Traceback" not in err
    assert not site.exists() or not any(site.iterdir())


def test_many_violations_name_the_first_and_count_the_others(clean, tmp_path, capsys):
    data = copy.deepcopy(clean)
    skips = [r for r in data["records"] if r["skipped"] and "judged_tolerance" not in r]
    for r in skips[:3]:
        r["passed"] = True
    bad = tmp_path / "results.json"
    bad.write_text(json.dumps(data))
    assert main(["report", "--results", str(bad), "--out", str(tmp_path / "site")]) == 2
    err = capsys.readouterr().err
    first = data["records"].index(skips[0])
    assert f"$.records[{first}].passed: expected null, got true" in err
    assert "(2 more violations after it)" in err and err.count("\n") == 1


def test_a_baseline_that_breaks_the_schema_is_refused(baseline, runs, tmp_path, capsys):
    data = json.loads(baseline.read_text())
    data["records"][_skipped(data)]["passed"] = True
    bad = tmp_path / "baseline.json"
    bad.write_text(json.dumps(data))
    assert schema_violations(data)
    code = main(["gate", "--baseline", str(bad), "--results", str(runs["clean"])])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.startswith("crosscheck: error:") and err.count("\n") == 1 and str(bad) in err


# ---- the TypedDicts, the schema, the code and the docs agree ---------------------------------

# the TypedDict of each object the schema describes (the baseline is the gate's file)
TYPED = {
    "#": R.Results,
    "#/$defs/meta": R.Meta,
    "#/$defs/machine": R.Machine,
    "#/$defs/metrics": R.Metrics,
    "#/$defs/record": R.Record,
    "#/$defs/finding": R.Finding,
    "#/$defs/projection": R.Projection,
    "#/$defs/series": R.Series,
    "#/$defs/agreement": R.AgreementMatrix,
}
DEF_OF = {td.__name__: pointer for pointer, td in TYPED.items()}


def _object_pointers(schema: dict) -> set[str]:
    """Every object the schema declares fields of, as a JSON pointer."""
    out = set()

    def walk(node, pointer):
        if isinstance(node, dict):
            if node.get("type") == "object" and "properties" in node:  # not a rule's subschema
                out.add(pointer)
            for k, v in node.items():
                walk(v, f"{pointer}/{k}")
        elif isinstance(node, list):
            for k, v in enumerate(node):
                walk(v, f"{pointer}/{k}")

    walk(schema, "#")
    return out


def _annotation_shape(tp):
    """A type annotation as the JSON it allows: ("string",), ("enum", values), ("array", item),
    ("map", value), ("object", pointer), or ("union", shapes)."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is typing.Literal:
        return ("enum", frozenset(args))
    if origin in (typing.Union, types.UnionType):
        return ("union", frozenset(_annotation_shape(a) for a in args))
    if origin is list:
        return ("array", _annotation_shape(args[0]))
    if origin is dict:
        return ("map", _annotation_shape(args[1]))
    if typing.is_typeddict(tp):
        return ("object", DEF_OF[tp.__name__])
    names = {str: "string", int: "integer", float: "number", bool: "boolean", type(None): "null"}
    return (names[tp],)


def _schema_shape(node, pointer: str):
    """The same for a schema node (at `pointer`)."""
    if "$ref" in node and len(set(node) - {"$ref", "description"}) == 0:
        return _schema_shape(_pointer(results_schema(), node["$ref"]), node["$ref"])
    if "enum" in node:
        return ("enum", frozenset(node["enum"]))
    if "const" in node:  # failure: always true
        return ({True: "boolean", False: "boolean"}.get(node["const"], "null"),)
    kinds = [node["type"]] if isinstance(node["type"], str) else node["type"]
    shapes = []
    for kind in kinds:
        if kind == "array":
            shapes.append(("array", _schema_shape(node["items"], pointer + "/items")))
        elif kind == "object" and "properties" in node:
            shapes.append(("object", pointer))
        elif kind == "object":
            shapes.append(("map", _schema_shape(node["additionalProperties"], pointer)))
        else:
            shapes.append((kind,))
    return shapes[0] if len(shapes) == 1 else ("union", frozenset(shapes))


@pytest.mark.parametrize("pointer", list(TYPED))
def test_typeddicts_and_schema_agree(pointer):
    """Each TypedDict and its schema object: the same fields, the same required ones, and each
    field the same JSON types (enums the same values)."""
    td, node = TYPED[pointer], _pointer(results_schema(), pointer)
    hints = typing.get_type_hints(td)
    assert set(hints) == set(node["properties"]), (
        f"in the TypedDict only: {sorted(set(hints) - set(node['properties']))}; "
        f"in the schema only: {sorted(set(node['properties']) - set(hints))}"
    )
    assert set(td.__required_keys__) == set(node.get("required", []))
    for name, tp in hints.items():
        field = node["properties"][name]
        assert _annotation_shape(tp) == _schema_shape(field, f"{pointer}/properties/{name}"), name


def test_every_schema_object_has_its_typeddict():
    assert _object_pointers(results_schema()) - set(TYPED) == {
        "#/$defs/baseline",
        "#/$defs/baseline/properties/meta",
    }


def test_enums_are_the_codes_own_names():
    """The schema's enums (through the TypedDicts' Literals, held equal above) are the names the
    code uses: the metrics, the formulations, the agreement quantities, the checks."""
    from crosscheck.checks import agreement
    from crosscheck.checks.tolerances import METRICS
    from crosscheck.run.checks import GENERIC_SUFFIX
    from reference.system import FORMULATIONS

    assert set(typing.get_args(R.Metric)) == set(METRICS)
    assert set(typing.get_args(R.Formulation)) == set(FORMULATIONS)
    quantity = typing.get_type_hints(R.AgreementMatrix)["quantity"]
    assert set(typing.get_args(quantity)) == set(agreement.QUANTITIES)
    checks = set(typing.get_args(R.Check))
    assert {c + GENERIC_SUFFIX for c in ("formulations", "instantaneous")} <= checks


def test_record_refuses_fields_the_contract_does_not_declare():
    from crosscheck.checks.tolerances import STATE_MAP

    rec = R.record("m", "kane", "e", "instantaneous", "state_map", 0.0, STATE_MAP, worst_state=0)
    skip = R.record("m", "kane", "e", "instantaneous", "mass_matrix", None, None, "not mapped")
    record_schema = Draft202012Validator(
        {"$defs": results_schema()["$defs"], "$ref": "#/$defs/record"}
    )
    assert record_schema.is_valid(rec) and record_schema.is_valid(skip)
    assert rec["passed"] is True and skip["passed"] is None and "metric" not in skip
    with pytest.raises(TypeError, match="'colour'"):
        R.record("m", "kane", "e", "instantaneous", "state_map", 0.0, STATE_MAP, colour="red")
    with pytest.raises(TypeError, match="'colour'"):
        R.annotated(rec, colour="red")
    assert R.annotated(rec, variant="tree")["variant"] == "tree"


def test_schema_is_valid_and_shipped_with_the_package():
    Draft202012Validator.check_schema(results_schema())
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert RESULTS_SCHEMA in pyproject["tool"]["setuptools"]["package-data"]["crosscheck.schema"]
    assert any(d.startswith("jsonschema") for d in pyproject["project"]["dependencies"])


def _doc_sections(text: str) -> dict[str, set[str]]:
    """{schema pointer: the fields of the first table after its marker} in docs/results.md."""
    out = {}
    for match in re.finditer(r"<!-- schema: (\S+) -->", text):
        lines = text[match.end() :].splitlines()
        start = next(i for i, ln in enumerate(lines) if ln.startswith("|"))
        rows = []
        for ln in lines[start + 2 :]:  # past the header and its separator
            if not ln.startswith("|"):
                break
            rows.append(ln)
        out[match.group(1)] = {re.match(r"\| `([^`]+)` \|", row).group(1) for row in rows}
    return out


def test_docs_describe_every_schema_field():
    """docs/results.md has a table for every object of the schema, listing exactly its fields,
    and names every value of its enums."""
    text = (ROOT / "docs" / "results.md").read_text()
    sections = _doc_sections(text)
    schema = results_schema()
    assert set(sections) == _object_pointers(schema)
    for pointer, fields in sections.items():
        declared = set(_pointer(schema, pointer)["properties"])
        assert fields == declared, (
            f"{pointer}: in the docs only {sorted(fields - declared)}, "
            f"in the schema only {sorted(declared - fields)}"
        )

    def enums(node):
        if isinstance(node, dict):
            yield from node.get("enum", [])
            for v in node.values():
                yield from enums(v)
        elif isinstance(node, list):
            for v in node:
                yield from enums(v)

    missing = sorted({e for e in enums(schema) if f"`{e}`" not in text})
    assert not missing, f"enum values docs/results.md does not name: {missing}"


def test_every_field_is_described_in_the_schema():
    """Each field of each object has a "description" (on the field or on the $def it refers
    to)."""
    schema = results_schema()
    for pointer in _object_pointers(schema):
        for name, field in _pointer(schema, pointer)["properties"].items():
            target = _pointer(schema, field["$ref"]) if "$ref" in field else field
            assert field.get("description") or target.get("description"), f"{pointer}: {name}"
