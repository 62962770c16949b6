"""One pipeline configuration: read from the core, dumped, loaded and compared whole."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import pytest

import solid
from solid import _solid
from solid.config import REMOVED_DETECTOR_KEYS, ConfigFileError, InputOptions, PipelineConfig, descriptor_fields, detector_fields


def test_fields_and_defaults_come_from_the_core() -> None:
    assert list(descriptor_fields()) == list(solid.SolidConfig.preset("hdl64").to_dict())
    assert list(detector_fields()) == list(solid.DetectorConfig().to_dict())
    cfg = PipelineConfig.preset("avia")
    assert cfg.descriptor == solid.SolidConfig.preset("avia")
    assert cfg.detector == solid.DetectorConfig.preset("avia")
    assert cfg.radius == _solid.DEFAULT_RADIUS
    # the docs/spec.md §1 defaults of SolidConfig() are the core's (those of every preset)
    bare = solid.SolidConfig(fov_up=2.0, fov_down=-24.8, n_elevation=64)
    assert bare == solid.SolidConfig.preset("hdl64")
    # every preset has its own measured loop threshold, used by a detector made from its config
    for name in solid.presets():
        thr = solid.DetectorConfig.preset(name).threshold
        assert 0 < thr < 1
        det = solid.LoopDetector(solid.SolidConfig.preset(name))
        assert det.threshold == thr and det.config == solid.DetectorConfig.preset(name)
        assert solid.LoopDetector(solid.SolidConfig.preset(name, max_range=40.0)).threshold == thr


def test_dump_load_round_trip_and_partial_files(tmp_path: Path) -> None:
    cfg = PipelineConfig.preset("avia", descriptor={"max_range": 40.0}, detector={"exclude_meters": 20.0, "top_k": 5}, radius=3.0, input={"fov": 60.0})
    cfg.dump(tmp_path / "c.json")
    back = PipelineConfig.load(tmp_path / "c.json")
    assert back == cfg and hash(back) == hash(cfg)
    assert back.descriptor.max_range == 40.0 and back.detector.top_k == 5 and back.input.fov == 60.0
    # missing sections and keys take their defaults
    (tmp_path / "p.json").write_text(json.dumps({"preset": "vlp16", "detector": {"threshold": 0.05}}))
    p = PipelineConfig.load(tmp_path / "p.json")
    assert p.descriptor == solid.SolidConfig.preset("vlp16") and p.detector.threshold == 0.05
    assert p.detector.exclude_frames == solid.DetectorConfig().exclude_frames


def test_negative_zero_is_normalised() -> None:
    a = PipelineConfig.preset("hdl64", descriptor={"voxel_size": -0.0}, input={"occlude_center": -0.0})
    b = PipelineConfig.preset("hdl64", descriptor={"voxel_size": 0.0}, input={"occlude_center": 0.0})
    assert a == b and hash(a) == hash(b) and a.dumps() == b.dumps()
    assert '-0.0' not in a.dumps()
    c1 = solid.SolidConfig.preset("hdl64", voxel_size=-0.0)
    c2 = solid.SolidConfig.preset("hdl64", voxel_size=0.0)
    assert c1 == c2 and hash(c1) == hash(c2) and c1.fingerprint == c2.fingerprint


@pytest.mark.parametrize(
    "doc, message",
    [
        ({"preset": "avia", "descriptors": {}}, "unknown sections descriptors"),
        ({"preset": "avia", "detector": {"treshold": 0.1}}, "unknown detector keys treshold"),
        ({"preset": "lidar9000"}, "unknown preset"),
        ({"descriptor": {"n_range": 40}}, "give a preset or the descriptor fields"),
        ({"preset": "avia", "detector": {"threshold": 2.0}}, "threshold"),
        ({"preset": "avia", "detector": {"exclude_frames": -1}}, "exclude_frames"),
        ({"preset": "avia", "detector": {"top_k": True}}, "top_k"),
        ({"preset": "avia", "evaluation": {"radius": -1}}, "radius"),
        ({"preset": "avia", "input": {"fov": 0}}, "input.fov"),
        ({"preset": "avia", "input": {"frames": 12}}, "input.frames"),
        ([1, 2], "expected a JSON object"),
    ],
)
def test_invalid_configurations_name_the_problem(tmp_path: Path, doc: object, message: str) -> None:
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(doc))
    with pytest.raises((solid.ConfigError, TypeError), match=message):
        PipelineConfig.load(f)


def test_a_config_naming_a_removed_check_loads_without_it_and_says_so(tmp_path: Path) -> None:
    """The config.json of a run made before a check was removed: its detector keys are dropped
    with a warning that names them, the rest is read as written."""
    doc = PipelineConfig.preset("avia", detector={"exclude_meters": 12.0}).to_dict()
    doc["detector"].update(view_fov_deg=70.4, view_min_overlap_deg=20.0, pose_candidate_shift_m=3.0)
    f = tmp_path / "config.json"
    f.write_text(json.dumps(doc))
    with pytest.warns(UserWarning, match="pose_candidate_shift_m, view_fov_deg, view_min_overlap_deg ignored"):
        cfg = PipelineConfig.load(f)
    assert cfg == PipelineConfig.preset("avia", detector={"exclude_meters": 12.0})
    assert not set(REMOVED_DETECTOR_KEYS) & set(cfg.to_dict()["detector"])


def test_setting_a_removed_detector_key_is_refused_saying_it_was_removed() -> None:
    """A call naming a removed key is code to fix, not a file to keep reading: refused (as C's
    solid_detector_config_set refuses it), the message saying it was removed, in which version,
    why and that nothing replaces it; the keys are the core's one table."""
    assert set(REMOVED_DETECTOR_KEYS) == {"pose_candidate_shift_m", "view_fov_deg", "view_min_overlap_deg"}
    with pytest.raises(TypeError, match=r'"view_min_overlap_deg" was removed in solid \d+\.\d+\.\d+: the view check was removed.*nothing replaces it'):
        solid.DetectorConfig(view_min_overlap_deg=20.0)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="unknown DetectorConfig parameter"):
        solid.DetectorConfig(no_such_key=1.0)  # type: ignore[call-arg]


def test_hostile_files_are_refused(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000)
    with pytest.raises(ConfigFileError, match="deep.json"):
        PipelineConfig.load(deep)
    (tmp_path / "dir.json").mkdir()
    with pytest.raises(ConfigFileError, match="not a regular file"):
        PipelineConfig.load(tmp_path / "dir.json")
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConfigFileError, match="not a text file"):
        PipelineConfig.load(tmp_path / "bin.json")
    with pytest.raises(FileNotFoundError):
        PipelineConfig.load(tmp_path / "missing.json")


def test_detector_config_pickles_and_keeps_the_base_preset() -> None:
    d = solid.DetectorConfig.preset("avia", exclude_meters=5.0)
    assert pickle.loads(pickle.dumps(d)) == d
    c = solid.SolidConfig.preset("avia").replace(max_range=40.0)
    assert c.base_preset == "avia"
    c2 = pickle.loads(pickle.dumps(c))
    assert c2 == c and c2.base_preset == "avia"
    assert solid.SolidConfig(fov_up=1.0, fov_down=-1.0, n_elevation=4).base_preset is None
    with pytest.raises(solid.ConfigError, match="exclude_frames"):
        solid.DetectorConfig(exclude_frames=-1)
    with pytest.raises(TypeError, match="unknown DetectorConfig parameter"):
        solid.DetectorConfig(exclude=3)  # type: ignore[call-arg]
    assert InputOptions().to_dict()["fov"] is None
