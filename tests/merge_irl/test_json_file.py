"""The one reader of JSON files (:mod:`merge_irl.json_file`): one-line errors naming the file and
the field path, for a nested bad field of every learned-file format; and the driver-format
registry reads each file once."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import sim.drivers  # noqa: F401  # registers the built-in formats
from irl.config import IRLConfig
from irl.domains.merge.car_following import CF_FEATURES
from irl.domains.merge.cf_logit import CarFollowingLogit
from irl.errors import ModelFileError
from irl.planning.driver import PlanningDriver
from irl.planning.features import Shape
from irl.planning.model import PlannerConfig
from irl.result import SavedModel
from merge_irl import json_file
from merge_irl.json_file import field_path, read_json
from sim.drivers import formats

ACC = (-10.0, -4.0, 0.0, 4.0, 10.0)


def _model() -> dict:
    return SavedModel(method="qavg", theta=np.array([0.5, -1.0]), loglik=-3.0, q=np.ones((3, 2)),
                      config=IRLConfig(), feature_names=("a", "b")).to_json_dict()


def _cf() -> dict:
    return CarFollowingLogit(np.zeros(len(CF_FEATURES)), ACC, 0.3).to_json_dict()


def _planner() -> dict:
    config = PlannerConfig(decision_step_s=0.3)
    return PlanningDriver(np.zeros(len(config.feature_names)), config.feature_names, config, Shape(), 0.3,
                          ACC).to_json_dict()


@pytest.mark.parametrize("make, load, change, line", [
    (_model, SavedModel.load, lambda d: d["settings"].update(gamma=1.5),
     r"model\.json: settings\.gamma: must be in \[0, 1\), got 1\.5$"),
    (_model, SavedModel.load, lambda d: d["settings"].update(max_outer="5"),
     r"model\.json: settings\.max_outer: must be an integer, got '5'$"),
    (_model, SavedModel.load, lambda d: d["q"][1].__setitem__(0, "x"), r"model\.json: q\[1\]\[0\]: must be a number"),
    (_model, SavedModel.load, lambda d: d["bin_edges"].update(d_AC=[1.0, True]),
     r"model\.json: bin_edges\.d_AC\[1\]: must be a number, got True$"),
    (_cf, CarFollowingLogit.load, lambda d: d["gap_need"].update(clip="25"),
     r"model\.json: gap_need\.clip: must be a number, got '25'$"),
    (_cf, CarFollowingLogit.load, lambda d: d["theta"].__setitem__(2, None),
     r"model\.json: theta\[2\]: must be a number, got None$"),
    (_planner, PlanningDriver.load, lambda d: d["config"].update(depth="2"),
     r"model\.json: config\.depth: must be an integer, got '2'$"),
    (_planner, PlanningDriver.load, lambda d: d["shape"].pop("T_s"), r"model\.json: shape\.T_s: missing$"),
    (_planner, PlanningDriver.load, lambda d: d["config"].update(nope=1), r"model\.json: config\.nope: unknown field$"),
])
def test_a_nested_bad_field_is_named_by_its_path_on_one_line(tmp_path, make, load, change, line):
    data = make()
    change(data)
    p = tmp_path / "model.json"
    p.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match=line) as e:
        load(p)
    assert str(e.value).startswith(str(p)) and "\n" not in str(e.value)


def test_read_json_names_the_file_for_each_way_it_fails(tmp_path):
    with pytest.raises(ModelFileError, match=r"none\.json: no such thing$"):
        read_json(tmp_path / "none.json", what="thing", error=ModelFileError)
    with pytest.raises(ModelFileError, match="cannot read thing"):
        read_json(tmp_path, what="thing", error=ModelFileError)
    (tmp_path / "b.json").write_bytes(b"\xff\xfe{")
    with pytest.raises(ModelFileError, match=r"b\.json: not a JSON thing \(not UTF-8"):
        read_json(tmp_path / "b.json", what="thing", error=ModelFileError)
    (tmp_path / "d.json").write_text("[" * 100_000)
    with pytest.raises(ModelFileError, match=r"d\.json: not a JSON thing \(RecursionError"):
        read_json(tmp_path / "d.json", what="thing", error=ModelFileError)
    assert field_path(("a", 0, "b", 2)) == "a[0].b[2]" and field_path(()) == "<top>"


@pytest.mark.parametrize("make", [_model, _cf, _planner])
def test_the_registry_reads_a_learned_file_once(tmp_path, monkeypatch, make):
    p = tmp_path / "learned.json"
    p.write_text(json.dumps(make()))
    reads: list[Path] = []
    real = Path.read_text

    def counting(self: Path, *a, **kw) -> str:
        reads.append(self)
        return real(self, *a, **kw)

    monkeypatch.setattr(Path, "read_text", counting)
    learned = formats.load_driver(p, role=None)
    assert reads == [p]
    assert type(learned) in (SavedModel, CarFollowingLogit, PlanningDriver)
    if make is not _model:  # (this small tabular model is no merge policy)
        reads.clear()
        formats.driver_policy(p)
        assert reads == [p]
    assert json_file.read_json is formats.read_json  # the registry's one reader is the shared one


def test_the_scenario_schemas_cover_their_dataclasses_and_name_nested_fields():
    from dataclasses import fields

    from scenarios.errors import SpecError
    from scenarios.spec.model import DemandSpec, RoadSpec, VTypeSpec
    from scenarios.spec.parse import spec_from_dict
    from scenarios.spec.schema import DemandSchema, RoadSchema, VTypeSchema

    for schema, cls in ((RoadSchema, RoadSpec), (DemandSchema, DemandSpec), (VTypeSchema, VTypeSpec)):
        assert set(schema.model_fields) == {f.name for f in fields(cls)}, cls.__name__
    bad = {"name": "s", "drivers": {"truck": [{"id": "t", "lc_params": {"lcSpeedGain": [1]}}]}}
    with pytest.raises(SpecError, match=r"^s\.toml: drivers\.truck\[0\]\.lc_params\.lcSpeedGain: must be a number, "
                                        r"string or boolean, got list$"):
        spec_from_dict(bad, source="s.toml")


def test_the_params_file_names_a_nested_field(tmp_path):
    from analysis.calibration.params_file import load_result
    from scenarios.errors import SpecError

    p = tmp_path / "params.toml"
    p.write_text('model = "idm"\n[population]\ntau = 1.0\n[spread.tau]\nmean = 1.0\nstd = "x"\nmedian = 1.0\n'
                 'q10 = 1.0\nq90 = 1.0\n')
    with pytest.raises(SpecError, match=r"params\.toml: spread\.tau\.std: must be a number, got 'x'$"):
        load_result(p)


def test_the_npz_manifest_names_the_array_and_entry(tmp_path):
    from irl.errors import DemonstrationError
    from irl.io import load_npz

    p = tmp_path / "demos.npz"
    np.savez(p, features=np.zeros((4, 2, 1)), states=np.array([0, 1, 2]), actions=np.array([0, 1, 0.5]),
             offsets=np.array([0, 3]))
    with pytest.raises(DemonstrationError, match=r"demos\.npz: actions: entry 2 = 0\.5 is not an integer$"):
        load_npz(p)
