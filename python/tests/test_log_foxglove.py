"""The MCAP log against Foxglove's own definitions of its well-known schemas (the
foxglove-schemas-protobuf package's descriptors, independent of asserv.log), and the MCAP and the
CSV against the simulator's trace over random runs.

Foxglove's JSON encoding of a well-known schema uses the protobuf definition's field names, with
``{"sec", "nsec"}`` for a time or a duration and an enum as its number: every message of every
topic is walked against the descriptor of the schema its channel names."""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.descriptor import Descriptor, FieldDescriptor
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from asserv import field, log
from asserv.driver import Board
from asserv.sim import Simulator

FOXGLOVE = {
    "foxglove.PoseInFrame": PoseInFrame.DESCRIPTOR,
    "foxglove.FrameTransform": FrameTransform.DESCRIPTOR,
    "foxglove.SceneUpdate": SceneUpdate.DESCRIPTOR,
}
_TIMES = ("google.protobuf.Timestamp", "google.protobuf.Duration")
_FLOATS = (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT)
_UINTS = (FieldDescriptor.TYPE_UINT32, FieldDescriptor.TYPE_FIXED32, FieldDescriptor.TYPE_UINT64)


def conforms(value: Any, desc: Descriptor, where: str = "") -> None:
    """Assert that ``value`` is ``desc``'s message in Foxglove's JSON form, every field given."""
    assert isinstance(value, dict), f"{where}: {desc.full_name} is an object"
    if desc.full_name in _TIMES:
        assert set(value) == {"sec", "nsec"}, where
        assert all(type(value[k]) is int for k in value), where
        assert 0 <= value["nsec"] < 1_000_000_000 and value["sec"] >= 0, where
        return
    names = {f.name for f in desc.fields}
    assert set(value) <= names, f"{where}: {set(value) - names} not in {desc.full_name}"
    assert set(value) == names, f"{where}: {names - set(value)} missing from {desc.full_name}"
    for f in desc.fields:
        v = value[f.name]
        if f.is_repeated:
            assert isinstance(v, list), f"{where}.{f.name}"
            for i, item in enumerate(v):
                _field(item, f, f"{where}.{f.name}[{i}]")
        else:
            _field(v, f, f"{where}.{f.name}")


def _field(v: Any, f: FieldDescriptor, where: str) -> None:
    if f.type == FieldDescriptor.TYPE_MESSAGE:
        conforms(v, f.message_type, where)
    elif f.type == FieldDescriptor.TYPE_ENUM:
        assert type(v) is int and v in {e.number for e in f.enum_type.values}, where
    elif f.type in _FLOATS:
        assert type(v) in (int, float) and math.isfinite(v), where
    elif f.type == FieldDescriptor.TYPE_STRING:
        assert isinstance(v, str), where
    elif f.type == FieldDescriptor.TYPE_BOOL:
        assert isinstance(v, bool), where
    elif f.type in _UINTS:
        assert type(v) is int and v >= 0, where
    else:
        raise AssertionError(f"{where}: a field of type {f.type} is not expected")


def read_all(path: Path) -> tuple[dict[str, str], dict[str, list[tuple[int, dict[str, Any]]]]]:
    """Schema name by topic, and (log time ns, message) by topic, with the mcap library."""
    schemas: dict[str, str] = {}
    msgs: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    with path.open("rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert schema is not None and schema.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            schemas[channel.topic] = schema.name
            # The schema registered is JSON, and an object schema.
            assert json.loads(schema.data)["type"] == "object"
            msgs.setdefault(channel.topic, []).append((message.log_time, json.loads(message.data)))
    return schemas, msgs


def _check_against_trace(sim: Simulator, tmp: Path) -> None:
    tr = sim.trace
    rows = log.from_sim(sim)
    m, c = tmp / "run.mcap", tmp / "run.csv"
    before = time.time_ns()
    log.save(rows, mcap=m, csv=c, field=sim.field, outline=log.Outline.of(sim))
    after = time.time_ns()
    schemas, msgs = read_all(m)
    # Dated on the wall clock: the start of the recording, plus the run's time.
    back = log.read_mcap(m)
    start = back.start_ns
    assert start is not None and before <= start <= after
    assert back.profile == log.PROFILE
    assert schemas == log.TOPICS
    # Every Foxglove message conforms to Foxglove's definition of its schema.
    for topic, name in schemas.items():
        if name in FOXGLOVE:
            for _, msg in msgs[topic]:
                conforms(msg, FOXGLOVE[name], topic)
    # /asserv: one message a tick, at its time, with the trace's values; the CSV the same.
    samples = msgs["/asserv"]
    assert len(samples) == len(tr)
    ns = np.array([t for t, _ in samples])
    np.testing.assert_array_equal(ns - start, np.maximum(0, np.round(tr["t_s"] * 1e9)).astype(int))
    # Each message's own timestamp is its log time.
    for topic in ("/pose/estimate", "/tf"):
        for t, msg in msgs[topic]:
            assert msg["timestamp"]["sec"] * 10**9 + msg["timestamp"]["nsec"] == t, topic
    back_csv = log.read_csv(c)
    for name in log.LOG_FIELDS:
        col = np.array([math.nan if s[name] is None else s[name] for _, s in samples])
        np.testing.assert_array_equal(col, back_csv[name], err_msg=name)
        if name in (tr.dtype.names or ()):
            np.testing.assert_array_equal(col, tr[name], err_msg=name)
    # The poses and the transforms: the trace's, in metres, the heading about z.
    for topic, cols in (("/pose/estimate", "est_"), ("/pose/true", "")):
        poses = msgs[topic]
        assert len(poses) == len(tr)
        x = np.array([p["pose"]["position"]["x"] for _, p in poses])
        y = np.array([p["pose"]["position"]["y"] for _, p in poses])
        np.testing.assert_allclose(x * 1000, tr[f"{cols}x_mm"], atol=1e-9)
        np.testing.assert_allclose(y * 1000, tr[f"{cols}y_mm"], atol=1e-9)
        q = [p["pose"]["orientation"] for _, p in poses]
        h = np.degrees([2 * math.atan2(o["z"], o["w"]) for o in q])
        d = (h - tr[f"{cols}heading_deg"] + 180) % 360 - 180
        np.testing.assert_allclose(d, 0, atol=1e-7)
    tf = msgs["/tf"]
    assert len(tf) == 2 * len(tr)
    assert [t["child_frame_id"] for _, t in tf[:2]] == ["robot", "robot_true"]
    # The field as a scene, once, in the frame the transforms hang from.
    ((_, scene),) = msgs["/field"]
    (entity,) = scene["entities"]
    assert entity["frame_id"] == "field" == tf[0][1]["parent_frame_id"]
    radii = sorted(cy["size"]["x"] * 500 for cy in entity["cylinders"])
    want = sorted(
        [b.radius_mm for b in sim.field.baskets]
        + [o.radius_mm for o in sim.field.obstacles if o.shape == "circle"]
    )
    assert radii == pytest.approx(want)


def test_a_run_conforms_to_foxglove_and_matches_its_trace(tmp_path: Path) -> None:
    sim = Simulator()
    board = Board(sim.bus)
    board.goto(-500, 200)
    sim.advance(4)
    _check_against_trace(sim, tmp_path)


def test_a_field_with_every_kind_of_thing_conforms(tmp_path: Path) -> None:
    """Every primitive the field scene uses (borders, lines, baskets, round and square
    obstacles), and a log without the truth (a real board)."""
    obstacles = (
        field.Obstacle("circle", 100, 200, radius_mm=80),
        field.Obstacle("box", -300, 0, 0, 50, 120),
    )
    fld = dataclasses.replace(field.load(), obstacles=obstacles)
    scene = log.field_scene(fld)
    conforms(scene, FOXGLOVE["foxglove.SceneUpdate"], "/field")
    conforms(log.robot_scene(log.Outline(), ["robot"]), FOXGLOVE["foxglove.SceneUpdate"], "/robot")
    (entity,) = scene["entities"]
    assert len(entity["lines"]) == 1 + len(fld.lines) and fld.lines
    assert len(entity["cylinders"]) == len(fld.baskets) + 1
    box = entity["cubes"][-1]  # after the table
    assert box["size"]["x"] == pytest.approx(0.1) and box["size"]["y"] == pytest.approx(0.24)
    assert box["pose"]["position"]["x"] == pytest.approx(-0.3)
    rows = log.empty(3)
    rows["t_s"] = [0.0, 0.02, 0.04]
    rows["est_x_mm"], rows["est_y_mm"], rows["est_heading_deg"] = 1.0, 2.0, 3.0
    m = tmp_path / "board.mcap"
    log.save(rows, mcap=m, field=fld)
    schemas, msgs = read_all(m)
    assert "/pose/true" not in schemas
    for topic, name in schemas.items():
        for _, msg in msgs.get(topic, []):
            if name in FOXGLOVE:
                conforms(msg, FOXGLOVE[name], topic)
    assert all(t["child_frame_id"] == "robot" for _, t in msgs["/tf"])


GOTO = st.tuples(st.integers(-1200, 1200), st.integers(-850, 850))


@given(gotos=st.lists(GOTO, min_size=1, max_size=3), seconds=st.floats(0.5, 2.5))
@settings(
    max_examples=5, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
def test_random_runs_mcap_and_csv_agree_with_the_trace(
    tmp_path: Path, gotos: list[tuple[int, int]], seconds: float
) -> None:
    """Any run (orders replaced while moving, shocks where they fall): the MCAP and the CSV hold
    the trace's values, and every Foxglove message conforms."""
    sim = Simulator()
    board = Board(sim.bus)
    board.set_vitesse_traj(80, 150)
    for x, y in gotos:
        board.goto(x, y)
        sim.advance(seconds)
    _check_against_trace(sim, tmp_path)
