"""asserv view in a real browser: Debian's chromium driven by Playwright (no browser download).

The page must draw the field, follow the simulated robot, send a GOTO on a click that the board
executes, and replay a log's poses. With ASSERV_SCREENSHOTS=DIR set, the tests also save the
screenshots of docs/view.md there (ASSERV_SCREENSHOTS=docs/img).
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Browser, Page, sync_playwright  # the dev extra (scripts/setup.sh)

from asserv import log, scenario, view
from asserv.driver import Board
from asserv.sim import Simulator

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = os.environ.get("ASSERV_CHROMIUM", "/usr/bin/chromium")
SHOTS = os.environ.get("ASSERV_SCREENSHOTS")


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    if not shutil.which(CHROMIUM):
        pytest.fail(f"{CHROMIUM} is missing: apt-get install chromium (scripts/setup.sh does)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield b
        b.close()


@pytest.fixture
def serve() -> Iterator[Callable[[view.Source], view.ViewServer]]:
    servers: list[view.ViewServer] = []

    def start(source: view.Source) -> view.ViewServer:
        srv = view.ViewServer(source, "127.0.0.1", 0)
        srv.start_thread()
        servers.append(srv)
        return srv

    yield start
    for s in servers:
        s.stop()


def _open(browser: Browser, srv: view.ViewServer, url: str | None = None) -> Page:
    """The page at ``url`` (by default the address asserv view prints, with the token); every
    answer of the server that is an error is kept in ``page.failed``."""
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    failed: list[str] = []
    page.on("response", lambda r: failed.append(f"{r.status} {r.url}") if r.status >= 400 else 0)
    page.failed = failed  # type: ignore[attr-defined]
    page.goto(url or srv.url)
    page.wait_for_function("window.asserv && window.asserv.info && window.asserv.frames > 0")
    return page


def _click(page: Page, x_mm: float, y_mm: float) -> None:
    """A click on the field at a field point."""
    px, py = page.evaluate("([x, y]) => window.asserv.toCanvas(x, y)", [x_mm, y_mm])
    box = page.locator("#field").bounding_box()
    assert box is not None
    scale = box["width"] / page.evaluate("document.getElementById('field').width")
    page.mouse.click(box["x"] + px * scale, box["y"] + py * scale)


def _pixel(page: Page, x_mm: float, y_mm: float) -> list[int]:
    """The field canvas's colour at a field point."""
    px: list[int] = page.evaluate(
        """([x, y]) => {
            const [px, py] = window.asserv.toCanvas(x, y);
            const c = document.getElementById('field').getContext('2d');
            return Array.from(c.getImageData(Math.round(px), Math.round(py), 1, 1).data);
        }""",
        [x_mm, y_mm],
    )
    return px


def _last(page: Page) -> dict[str, Any]:
    last: dict[str, Any] = page.evaluate("window.asserv.last")
    return last


#: The scrolling plots and their series' colours (view.js's PLOTS).
PLOT_SERIES = {
    "p_speed": {"v_set_mm_s": "#000000", "v_mm_s": "#1565c0"},
    "p_turn": {"omega_set_deg_s": "#000000", "omega_deg_s": "#1565c0"},
    "p_err": {"dist_err_mm": "#2e7d32", "angle_err_mm": "#6a1b9a"},
    "p_duty": {"duty_left": "#ef6c00", "duty_right": "#00838f"},
    "p_cur": {"current_left_A": "#ef6c00", "current_right_A": "#00838f"},
}


def _drawn(page: Page, canvas: str, colors: list[str]) -> list[int]:
    """How many pixels of each colour (within 40 of it) the plot's area has, legend apart."""
    counts: list[int] = page.evaluate(
        """([id, colors]) => {
            const cv = document.getElementById(id);
            const d = cv.getContext('2d').getImageData(49, 20, cv.width - 58, cv.height - 40).data;
            const rgb = colors.map((c) => [1, 3, 5].map((i) => parseInt(c.slice(i, i + 2), 16)));
            const n = rgb.map(() => 0);
            for (let i = 0; i < d.length; i += 4) {
                if (d[i + 3] < 200) continue;
                rgb.forEach((c, j) => {
                    if (Math.hypot(d[i] - c[0], d[i + 1] - c[1], d[i + 2] - c[2]) < 40) n[j] += 1;
                });
            }
            return n;
        }""",
        [canvas, colors],
    )
    return counts


def _shot(page: Page, name: str) -> None:
    if SHOTS:
        Path(SHOTS).mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(Path(SHOTS) / name), full_page=True)


def test_the_page_draws_the_field(browser: Browser, serve: Any) -> None:
    src = view.SimSource()
    src.set_paused(True)
    page = _open(browser, serve(src))
    fld = src.field
    # The border (black, 4 px) at the middle of the right side; a basket's centre (orange); the
    # table's green; the background outside the table (white).
    r, g, b, _ = _pixel(page, fld.length_mm / 2, 300)
    assert r < 60 and g < 60 and b < 60
    bk = fld.baskets[0]
    r, g, b, _ = _pixel(page, bk.x_mm, bk.y_mm)
    assert r > 200 and 120 < g < 210 and b < 150
    assert _pixel(page, 300, 300)[:3] == [232, 240, 228]
    assert _pixel(page, fld.length_mm / 2 + 200, 0)[:3] in ([255, 255, 255], [0, 0, 0])
    assert page.inner_text("#kind") == "simulator"
    assert page.locator(".bit").count() == 7


def test_the_pose_updates_while_the_simulator_runs(browser: Browser, serve: Any) -> None:
    scn = scenario.load(ROOT / "scenarios/annex.txt")
    srv = serve(view.SimSource(scn))
    page = _open(browser, srv)
    page.wait_for_function("window.asserv.last !== null")
    first = _last(page)
    page.click("button.speed[data-speed='5']")
    page.wait_for_function(f"window.asserv.last.t_s > {first['t_s'] + 2.5}")
    later = _last(page)
    moved = math.hypot(later["est_x_mm"] - first["est_x_mm"], later["est_y_mm"] - first["est_y_mm"])
    assert moved > 50
    # What the page shows is what the simulator did at that time.
    assert srv.source.sim.time_s >= later["t_s"]
    # Paused, the time stands still; the page shows the last sample it drew.
    page.click("#play")
    page.wait_for_function("window.asserv.state.paused === true")
    page.wait_for_function(
        "document.querySelector('#ex').innerText === window.asserv.last.est_x_mm.toFixed(1)"
    )
    t = _last(page)["t_s"]
    page.wait_for_timeout(500)
    assert _last(page)["t_s"] == t
    # The scrolling plots: speed and turn rate against their set points, the following errors,
    # the duties and the currents, every series drawn.
    for canvas, series in PLOT_SERIES.items():
        counts = _drawn(page, canvas, list(series.values()))
        assert all(n > 20 for n in counts), (canvas, dict(zip(series, counts, strict=True)))
    _shot(page, "view-sim.png")


def test_a_click_sends_a_goto_the_board_executes(browser: Browser, serve: Any) -> None:
    src = view.SimSource()
    srv = serve(src)
    page = _open(browser, srv)
    assert page.inner_text("#mode") == "driving the simulator: a click sends a GOTO"
    page.click("button.speed[data-speed='20']")
    target = (600.0, 300.0)
    _click(page, *target)
    # The target as the page first had it (it clears once the order is done: at x20 that can
    # come before a second look).
    sent = page.wait_for_function("window.asserv.state.target").json_value()
    assert math.hypot(sent[0] - target[0], sent[1] - target[1]) < 10  # a pixel is ~3.3 mm
    page.wait_for_function(
        "window.asserv.state.outcome === 'done' && !(window.asserv.last.status & 2)",
        timeout=30000,
    )
    truth = src.sim.true_pose()
    assert math.hypot(truth.x_mm - sent[0], truth.y_mm - sent[1]) < 15
    last = _last(page)
    assert math.hypot(last["est_x_mm"] - sent[0], last["est_y_mm"] - sent[1]) < 3
    assert page.failed == []  # type: ignore[attr-defined]
    _shot(page, "view-goto.png")


def test_a_replay_shows_the_logged_poses(browser: Browser, serve: Any, tmp_path: Path) -> None:
    sim = Simulator()
    board = Board(sim.bus)
    board.set_vitesse_traj(60, 100)
    board.goto(-500, 0)
    board.wait_idle(30)
    rows = log.from_sim(sim)
    path = tmp_path / "run.mcap"
    log.save(rows, mcap=path, field=sim.field, outline=log.Outline.of(sim))
    src = view.ReplaySource(path)
    src.set_speed(2)
    page = _open(browser, serve(src))
    assert page.inner_text("#kind") == "replay"
    page.wait_for_function("window.asserv.received > 50")
    for _ in range(3):
        last = _last(page)
        i = int(np.searchsorted(rows["t_s"], last["t_s"] - 1e-9))
        for name in ("est_x_mm", "est_y_mm", "x_mm", "y_mm", "heading_deg"):
            assert last[name] == pytest.approx(rows[name][i], abs=1e-3), name
        page.wait_for_timeout(300)
    # At the end of the log the replay pauses on its last row, the robot drawn where the log
    # says: the estimate's red reference point at its pose.
    page.wait_for_function("window.asserv.state.paused === true", timeout=20000)
    page.wait_for_timeout(200)
    last = _last(page)
    assert last["t_s"] == pytest.approx(rows["t_s"][-1])
    assert last["est_x_mm"] == pytest.approx(rows["est_x_mm"][-1], abs=1e-3)
    r, g, b, _ = _pixel(page, last["est_x_mm"], last["est_y_mm"])
    assert r > 150 and g < 120 and b < 120
    assert "end of the log" in page.inner_text("#message")
    _shot(page, "view-replay.png")


# ---- what the page may do (issue 33) ------------------------------------------------------------


def test_the_page_without_the_token_watches_and_sends_nothing(browser: Browser, serve: Any) -> None:
    src = view.SimSource()
    srv = serve(src)
    page = _open(browser, srv, srv.base_url)  # the address without its token
    assert page.inner_text("#mode").startswith("watching only: this address has no token")
    assert page.inner_text("#hint") == "clicks on the field send nothing here"
    assert page.locator("#play").is_disabled()
    assert page.locator("button.speed[data-speed='20']").is_disabled()
    page.wait_for_function("window.asserv.received > 100")  # it watches: the simulator runs
    _click(page, 600, 300)
    page.wait_for_timeout(500)
    assert page.evaluate("window.asserv.sent") == []
    assert src.target is None and src.outcome.orders == 0
    truth = src.sim.true_pose()
    assert math.hypot(truth.x_mm, truth.y_mm + 850) < 1  # where it started


class _OtherSite:
    """Another web site on this machine (another port: another origin), serving one page."""

    def __init__(self, html: str) -> None:
        import http.server
        import threading

        body = html.encode()

        class Page(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:
                self.send_response(200)
                self.send_header("Content-Type", "text/html")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args: Any) -> None:
                pass

        self.http = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
        threading.Thread(target=self.http.serve_forever, daemon=True).start()
        self.origin = f"http://127.0.0.1:{self.http.server_address[1]}"

    def close(self) -> None:
        self.http.shutdown()
        self.http.server_close()


@pytest.mark.parametrize("site", ["loopback", "http://evil.example/"])
def test_a_page_of_another_site_cannot_connect(browser: Browser, site: str) -> None:
    """The attack of issue 33 in a real browser: a page of another site opens the view's
    socket (even knowing the token) and sends a GOTO; the robot does not move. From another
    port of this machine the handshake reaches the view, which refuses its Origin (403) and
    logs it; chromium does not even let a public site's page reach a loopback address."""
    logged: list[str] = []
    src = view.SimSource()
    srv = view.ViewServer(src, "127.0.0.1", 0, log=logged.append)
    srv.start_thread()
    evil = f"""<!doctype html><script>
        window.events = [];
        const ws = new WebSocket("{srv.ws_url}");
        ws.onopen = () => {{
            window.events.push("open");
            ws.send(JSON.stringify({{type: "goto", x: 500, y: 300}}));
        }};
        ws.onerror = () => window.events.push("error");
        ws.onclose = () => window.events.push("close");
    </script>"""
    other = _OtherSite(evil)
    try:
        page = browser.new_page()
        if site == "loopback":
            page.goto(other.origin + "/")
        else:
            page.route(site, lambda r: r.fulfill(status=200, content_type="text/html", body=evil))
            page.goto(site)
        page.wait_for_function("window.events.includes('close')")
        assert "open" not in page.evaluate("window.events")
        page.wait_for_timeout(300)
        assert src.target is None and src.outcome.orders == 0
        if site == "loopback":
            assert len(logged) == 1, logged
            assert f"with Origin {other.origin}: only the page that this view serves" in logged[0]
    finally:
        other.close()
        srv.stop()


def test_the_order_count_and_the_icon(browser: Browser, serve: Any) -> None:
    """Issue 30: "none yet (1 orders)" while the first order runs, and a favicon 404."""
    src = view.SimSource()
    page = _open(browser, serve(src))
    assert page.inner_text("#outcome") == "none yet" and page.inner_text("#orders") == ""
    _click(page, 300, -850)
    page.wait_for_function("window.asserv.state.orders === 1")
    if not page.evaluate("window.asserv.state.outcome"):  # the order still runs (x1: ~2 s)
        page.wait_for_timeout(100)
        assert page.inner_text("#outcome") == "under way"
        assert page.inner_text("#orders") == "(1 order so far)"
    page.wait_for_function("window.asserv.state.outcome === 'done'", timeout=30000)
    page.wait_for_timeout(100)
    assert page.inner_text("#outcome") == "done"
    assert page.inner_text("#orders") == "(1 order so far)"
    icon = page.evaluate("document.querySelector('link[rel=icon]').href")
    assert icon.endswith("/favicon.svg")
    assert page.request.get(icon).status == 200
    assert page.failed == []  # type: ignore[attr-defined]


def test_both_wheels_show_when_they_agree(browser: Browser, serve: Any) -> None:
    """Issue 30: driving straight, the left and right duties (and currents) are the same, and
    one trace hid the other. Both colours are drawn now."""
    src = view.SimSource()
    page = _open(browser, serve(src))
    page.click("button.speed[data-speed='5']")
    src.goto(600, -850)  # straight ahead of the start pose (0, -850, heading 0): no turn
    page.wait_for_function("window.asserv.state.outcome === 'done'", timeout=30000)
    page.click("#play")
    page.wait_for_function("window.asserv.state.paused === true")
    page.wait_for_timeout(200)
    rows = page.evaluate("window.asserv.rows")
    ix = page.evaluate("window.asserv.ix")
    moving = [r for r in rows if abs(r[ix["duty_left"]]) > 0.05]
    assert len(moving) > 20
    assert all(abs(r[ix["duty_left"]] - r[ix["duty_right"]]) < 0.02 for r in moving)
    for canvas in ("p_duty", "p_cur"):
        series = PLOT_SERIES[canvas]
        counts = _drawn(page, canvas, list(series.values()))
        assert all(n > 40 for n in counts), (canvas, dict(zip(series, counts, strict=True)))


@pytest.mark.parametrize("control", [False, True])
def test_a_board_is_driven_from_the_page_only_with_control(
    browser: Browser, serve: Any, control: bool
) -> None:
    sim = Simulator()
    src = view.BoardSource(Board(sim.bus), hz=50, control=control)
    page = _open(browser, serve(src))
    mode = page.inner_text("#mode")
    _click(page, 300, -850)
    if not control:
        assert mode.startswith("watching: the board is watched, not driven")
        page.wait_for_timeout(500)
        assert page.evaluate("window.asserv.sent") == [] and src.target is None
        assert math.hypot(sim.true_pose().x_mm, sim.true_pose().y_mm + 850) < 1
        return
    assert mode == "driving the board: a click sends a GOTO"
    page.wait_for_function("window.asserv.state.outcome === 'done'", timeout=30000)
    assert sim.true_pose().x_mm == pytest.approx(300, abs=15)


def test_the_page_shows_a_reset(browser: Browser, serve: Any) -> None:
    """Issue 28: RESET_INFO on the panel, "none since power-on" at first; after a brown-out
    that lost the RAM, its cause and count and the lost pose, in red."""
    src = view.SimSource()
    page = _open(browser, serve(src))
    page.wait_for_function("document.getElementById('reset').textContent !== '-'")
    assert page.inner_text("#reset") == "none since power-on"

    def reset(s: Simulator) -> None:  # between two of the view's transactions
        if s.bus_busy:
            s.at(s.time_s + 0.0005, reset)
        else:
            s.reset("BROWN_OUT", keep_ram=False)

    src.sim.at(src.sim.time_s + 0.2, reset)
    page.wait_for_function(
        "document.getElementById('reset').textContent.startsWith('BROWN_OUT')", timeout=10000
    )
    assert page.inner_text("#reset") == (
        "BROWN_OUT, 1 since power-on; POSE LOST: orders refused until the position is set"
    )
    assert page.evaluate("document.getElementById('reset').classList.contains('lost')")
    assert page.failed == []  # type: ignore[attr-defined]
