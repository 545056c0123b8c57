"""The logs read by the reference MCAP reader, @mcap/core (what Foxglove and Lichtblick build
on), beside the Python reader: dates on the wall clock, the header's profile, the schemas, the
counts. scripts/setup.sh test installs it (npm ci in python/tests/mcap_js, versions pinned by
its package-lock.json); the tests fail, not skip, without it.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import json
import shutil
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asserv import cli, log

HERE = Path(__file__).resolve().parent / "mcap_js"
ROOT = Path(__file__).resolve().parents[2]


def reference(path: Path) -> dict[str, Any]:
    """What @mcap/core reads in ``path`` (python/tests/mcap_js/read.mjs)."""
    node = shutil.which("node")
    assert node is not None, "node is not installed: bash -c '. scripts/setup.sh test'"
    assert (HERE / "node_modules" / "@mcap" / "core").is_dir(), (
        "@mcap/core is not installed: bash -c '. scripts/setup.sh test'"
    )
    p = subprocess.run(
        [node, str(HERE / "read.mjs"), str(path)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert p.returncode == 0, p.stderr
    out: dict[str, Any] = json.loads(p.stdout)
    return out


def test_a_recorded_run_is_dated_on_the_wall_clock(tmp_path: Path) -> None:
    """`asserv sim run --mcap`: the reference reader finds the schemas, the counts the Python
    reader finds, and times that start when the recording did (not 1970)."""
    m = tmp_path / "annex.mcap"
    before = time.time_ns()
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli.main(["sim", "run", str(ROOT / "scenarios/annex.txt"), "--mcap", str(m)]) == 0
    after = time.time_ns()
    js = reference(m)
    py = log.read_mcap(m)

    assert js["profile"] == py.profile == log.PROFILE
    assert js["library"].startswith("asserv ")
    # the schemas, by topic, as written
    assert {t: v["schema"] for t, v in js["topics"].items()} == log.TOPICS
    assert all(v["schemaEncoding"] == "jsonschema" for v in js["topics"].values())
    assert all(v["messageEncoding"] == "json" for v in js["topics"].values())
    # the counts: one /asserv and two /tf a row, the field and the robot once
    n = len(py.rows)
    counts = {t: v["count"] for t, v in js["topics"].items()}
    assert counts["/asserv"] == n > 1000
    assert counts["/pose/estimate"] == counts["/pose/true"] == n
    assert counts["/tf"] == 2 * n
    assert counts["/field"] == counts["/robot"] == 1
    assert int(js["messageCount"]) == sum(counts.values()) and js["channelCount"] == 6
    for topic, msgs in py.messages.items():
        assert counts[topic] == len(msgs), topic
    # the dates: the wall clock at the start of the recording, plus the run's time
    start = py.start_ns
    assert start is not None and before <= start <= after
    assert int(js["metadata"]["asserv"]["start_ns"]) == start
    assert int(js["messageStartTime"]) == start + round(py.rows["t_s"][0] * 1e9)
    assert int(js["messageEndTime"]) == start + round(py.rows["t_s"][-1] * 1e9)
    day = datetime.datetime.fromtimestamp(int(js["messageStartTime"]) / 1e9, datetime.UTC)
    assert day.date() == datetime.datetime.fromtimestamp(before / 1e9, datetime.UTC).date() or (
        day.date() == datetime.datetime.fromtimestamp(after / 1e9, datetime.UTC).date()
    )
    # the first sample reads the same in both readers; integer columns are JSON integers
    first = js["topics"]["/asserv"]["firstMessage"]
    for name in log.LOG_FIELDS:
        v = float(py.rows[name][0])
        assert (first[name] is None) if np.isnan(v) else first[name] == v, name
    for name in log.INTEGER & set(log.LOG_FIELDS):
        assert first[name] is None or type(first[name]) is int, name


@settings(
    max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    start_ns=st.integers(0, 2**62),
    steps=st.lists(st.floats(0.0, 1000.0, allow_nan=False), min_size=1, max_size=20),
)
def test_any_start_and_times(tmp_path: Path, start_ns: int, steps: list[float]) -> None:
    """Whatever the start and the times, the reference reader finds start + t, to the ns."""
    rows = log.empty(len(steps))
    rows["t_s"] = np.cumsum(steps)
    rows["est_x_mm"] = rows["est_y_mm"] = rows["est_heading_deg"] = 0.0
    m = tmp_path / "r.mcap"
    log.save(rows, mcap=m, start_ns=start_ns)
    js = reference(m)
    want = [start_ns + max(0, round(t * 1e9)) for t in rows["t_s"]]
    asserv = js["topics"]["/asserv"]
    assert asserv["count"] == len(rows)
    assert int(asserv["first"]) == want[0] and int(asserv["last"]) == want[-1]
    assert int(js["metadata"]["asserv"]["start_ns"]) == start_ns


def test_a_missing_file_is_not_read(tmp_path: Path) -> None:
    """The reader is really run: a file that is not there makes it fail."""
    with pytest.raises(AssertionError, match=r"ENOENT|no such file"):
        reference(tmp_path / "none.mcap")
