// asserv view: draws the field, the robot and scrolling plots from the server's stream (/ws).
// Plain canvas drawing, no library: the page works in a pit without internet.
"use strict";

const PLOT_WINDOW_S = 10; // the plots' time span
const PATH_MAX = 20000; // path points kept
const HISTORY_MAX = 4000; // rows kept for the plots

// Everything the page knows; window.asserv lets tests and curious users look at it.
const view = {
  info: null,
  ix: {}, // column name -> index in a row
  rows: [], // recent rows (arrays of LOG_FIELDS values)
  estPath: [],
  truePath: [],
  last: null, // the last row, as an object
  state: {},
  received: 0, // rows received since the page opened
  pendingTarget: null,
  sent: [], // commands sent (tests)
  frames: 0, // field drawings
  access: { commands: false, drive: false, mode: "" }, // what the server lets this page do
  refused: [], // why the server refused this page's messages
  notice: "", // a refusal, shown for a few seconds
  noticeUntil: 0,
};
window.asserv = view;

const fieldCanvas = document.getElementById("field");
const fctx = fieldCanvas.getContext("2d");
let ws = null;

// ---- geometry -----------------------------------------------------------------------------
function transform() {
  const f = view.info.field;
  const m = 30;
  const s = Math.min((fieldCanvas.width - 2 * m) / f.length_mm,
    (fieldCanvas.height - 2 * m) / f.width_mm);
  return { s, cx: fieldCanvas.width / 2, cy: fieldCanvas.height / 2 };
}

// Field mm -> canvas pixels (y up on the field, down on the canvas).
function toCanvas(x, y) {
  const t = transform();
  return [t.cx + x * t.s, t.cy - y * t.s];
}
view.toCanvas = toCanvas;

function toField(px, py) {
  const t = transform();
  return [(px - t.cx) / t.s, (t.cy - py) / t.s];
}

function rowObject(r) {
  const o = {};
  view.info.fields.forEach((name, i) => { o[name] = r[i]; });
  return o;
}

// ---- the field ----------------------------------------------------------------------------
function drawField() {
  const f = view.info.field;
  const t = transform();
  fctx.clearRect(0, 0, fieldCanvas.width, fieldCanvas.height);
  const [x0, y0] = toCanvas(-f.length_mm / 2, f.width_mm / 2);
  fctx.fillStyle = "#e8f0e4";
  fctx.fillRect(x0, y0, f.length_mm * t.s, f.width_mm * t.s);
  for (const ln of f.lines) {
    const [a, b] = toCanvas(ln.x0_mm, ln.y0_mm);
    const [c, d] = toCanvas(ln.x1_mm, ln.y1_mm);
    fctx.strokeStyle = "#9e9e9e";
    fctx.lineWidth = Math.max(1, ln.width_mm * t.s);
    fctx.beginPath(); fctx.moveTo(a, b); fctx.lineTo(c, d); fctx.stroke();
  }
  for (const b of f.baskets) {
    const [x, y] = toCanvas(b.x_mm, b.y_mm);
    fctx.fillStyle = "rgba(255,152,0,0.55)";
    fctx.beginPath(); fctx.arc(x, y, b.radius_mm * t.s, 0, 2 * Math.PI); fctx.fill();
  }
  for (const o of f.obstacles) {
    fctx.fillStyle = "rgba(97,97,97,0.5)";
    const [x, y] = toCanvas(o.x_mm, o.y_mm);
    if (o.shape === "circle") {
      fctx.beginPath(); fctx.arc(x, y, o.radius_mm * t.s, 0, 2 * Math.PI); fctx.fill();
    } else {
      fctx.fillRect(x - o.half_x_mm * t.s, y - o.half_y_mm * t.s,
        2 * o.half_x_mm * t.s, 2 * o.half_y_mm * t.s);
    }
  }
  fctx.strokeStyle = f.borders ? "#111" : "#999";
  fctx.lineWidth = f.borders ? 4 : 1;
  fctx.setLineDash(f.borders ? [] : [6, 4]);
  fctx.strokeRect(x0, y0, f.length_mm * t.s, f.width_mm * t.s);
  fctx.setLineDash([]);
}

function drawPath(points, color, dash) {
  if (points.length < 2) return;
  fctx.strokeStyle = color;
  fctx.lineWidth = 1.5;
  fctx.setLineDash(dash);
  fctx.beginPath();
  points.forEach(([x, y], i) => {
    const [px, py] = toCanvas(x, y);
    if (i === 0) fctx.moveTo(px, py); else fctx.lineTo(px, py);
  });
  fctx.stroke();
  fctx.setLineDash([]);
}

function drawRobot(x, y, headingDeg, color) {
  const o = view.info.outline;
  const h = headingDeg * Math.PI / 180;
  const c = Math.cos(h), s = Math.sin(h);
  const hl = o.length_mm / 2, hw = o.width_mm / 2;
  const corners = [[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]].map(([u, v]) => {
    u += o.offset_x_mm; v += o.offset_y_mm;
    return toCanvas(x + c * u - s * v, y + s * u + c * v);
  });
  fctx.strokeStyle = color;
  fctx.fillStyle = color.replace("rgb(", "rgba(").replace(")", ",0.15)");
  fctx.lineWidth = 2;
  fctx.beginPath();
  corners.forEach(([px, py], i) => (i ? fctx.lineTo(px, py) : fctx.moveTo(px, py)));
  fctx.closePath(); fctx.fill(); fctx.stroke();
  // the heading: from the reference point to the front
  const [px, py] = toCanvas(x, y);
  const [fx, fy] = toCanvas(x + c * (hl + o.offset_x_mm), y + s * (hl + o.offset_x_mm));
  fctx.beginPath(); fctx.moveTo(px, py); fctx.lineTo(fx, fy); fctx.stroke();
  fctx.beginPath(); fctx.arc(px, py, 3, 0, 2 * Math.PI); fctx.fillStyle = color; fctx.fill();
}

function drawCross(x, y, color) {
  const [px, py] = toCanvas(x, y);
  fctx.strokeStyle = color; fctx.lineWidth = 2;
  fctx.beginPath();
  fctx.moveTo(px - 7, py - 7); fctx.lineTo(px + 7, py + 7);
  fctx.moveTo(px + 7, py - 7); fctx.lineTo(px - 7, py + 7);
  fctx.stroke();
}

const EST = "rgb(211,47,47)";
const TRU = "rgb(21,101,192)";
const LIDAR = "rgb(255,143,0)";

// Match play (issue 31): the queued points, the braking distance ahead, the lidar's hits.
function drawMatch(m, r) {
  if (!m || !r || r.est_x_mm === null) return;
  const pts = [[r.est_x_mm, r.est_y_mm], ...m.queue];
  drawPath(pts, "rgb(46,125,50)", [2, 4]);
  for (const [x, y] of m.queue) {
    const [px, py] = toCanvas(x, y);
    fctx.beginPath(); fctx.arc(px, py, 4, 0, 2 * Math.PI);
    fctx.fillStyle = "rgb(46,125,50)"; fctx.fill();
  }
  const o = view.info.outline;
  const h = r.est_heading_deg * Math.PI / 180;
  const front = o.length_mm / 2 + o.offset_x_mm;
  const ax = r.est_x_mm + Math.cos(h) * front, ay = r.est_y_mm + Math.sin(h) * front;
  const bx = ax + Math.cos(h) * m.braking_mm, by = ay + Math.sin(h) * m.braking_mm;
  if (m.braking_mm > 0) {
    const [pa, qa] = toCanvas(ax, ay), [pb, qb] = toCanvas(bx, by);
    fctx.strokeStyle = "rgba(211,47,47,0.8)"; fctx.lineWidth = 4;
    fctx.beginPath(); fctx.moveTo(pa, qa); fctx.lineTo(pb, qb); fctx.stroke();
  }
  fctx.fillStyle = LIDAR;
  for (const [x, y] of m.lidar) {
    const [px, py] = toCanvas(x, y);
    fctx.fillRect(px - 1.5, py - 1.5, 3, 3);
  }
  if (m.paused) {
    const [px, py] = toCanvas(r.est_x_mm, r.est_y_mm);
    fctx.fillStyle = "rgb(211,47,47)"; fctx.font = "bold 14px sans-serif";
    fctx.fillText("PAUSED", px + 12, py - 12);
  }
}

function drawScene() {
  if (!view.info) return;
  drawField();
  drawPath(view.truePath, TRU, []);
  drawPath(view.estPath, EST, [5, 4]);
  const target = view.state.target || view.pendingTarget;
  if (target) drawCross(target[0], target[1], "#000");
  const r = view.last;
  if (r) {
    if (r.x_mm !== null && view.info.truth) drawRobot(r.x_mm, r.y_mm, r.heading_deg, TRU);
    if (r.est_x_mm !== null) {
      drawRobot(r.est_x_mm, r.est_y_mm, r.est_heading_deg, EST);
      const t = transform();
      const [px, py] = toCanvas(r.est_x_mm, r.est_y_mm);
      fctx.strokeStyle = "rgba(211,47,47,0.6)"; fctx.lineWidth = 1;
      fctx.setLineDash([3, 3]);
      fctx.beginPath();
      fctx.arc(px, py, Math.max(2, (r.radius_mm || 0) * t.s), 0, 2 * Math.PI);
      fctx.stroke(); fctx.setLineDash([]);
    }
  }
  drawMatch(view.state.match, r);
  view.frames += 1;
}

// ---- the plots ----------------------------------------------------------------------------
// Each plot's series, drawn in this order: the first wide and solid, the second thin and dashed
// over it, so that where the two agree (a set point met, both wheels alike) both still show.
const UNDER = { width: 3, dash: [] };
const OVER = { width: 1.3, dash: [5, 4] };
const PLOTS = [
  { id: "p_speed", title: "speed [mm/s]", series: [["v_mm_s", "#1565c0", "measured"], ["v_set_mm_s", "#000", "set point"]] },
  { id: "p_turn", title: "turn rate [deg/s]", series: [["omega_deg_s", "#1565c0", "measured"], ["omega_set_deg_s", "#000", "set point"]] },
  { id: "p_err", title: "following error [mm at the wheels]", series: [["dist_err_mm", "#2e7d32", "distance"], ["angle_err_mm", "#6a1b9a", "angle"]] },
  { id: "p_duty", title: "duty [-1..1]", series: [["duty_left", "#ef6c00", "left"], ["duty_right", "#00838f", "right"]] },
  { id: "p_cur", title: "current [A]", series: [["current_left_A", "#ef6c00", "left"], ["current_right_A", "#00838f", "right"]] },
];

function drawPlot(p) {
  const cv = document.getElementById(p.id);
  const g = cv.getContext("2d");
  const W = cv.width, H = cv.height, L = 48, R = 8, T = 18, B = 18;
  g.clearRect(0, 0, W, H);
  g.fillStyle = "#222"; g.font = "12px sans-serif";
  g.fillText(p.title, L, 13);
  const rows = view.rows;
  if (!rows.length) return;
  const it = view.ix.t_s;
  const tEnd = rows[rows.length - 1][it];
  const t0 = tEnd - PLOT_WINDOW_S;
  let lo = Infinity, hi = -Infinity;
  const shown = rows.filter((r) => r[it] >= t0);
  for (const [key] of p.series) {
    const k = view.ix[key];
    for (const r of shown) {
      const v = r[k];
      if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    }
  }
  if (!isFinite(lo)) { g.fillText("(not known for this source)", L, H / 2); return; }
  if (hi - lo < 1e-6) { hi += 1; lo -= 1; }
  const pad = (hi - lo) * 0.08; hi += pad; lo -= pad;
  const X = (t) => L + (t - t0) / PLOT_WINDOW_S * (W - L - R);
  const Y = (v) => T + (hi - v) / (hi - lo) * (H - T - B);
  g.strokeStyle = "#ccc"; g.lineWidth = 1;
  g.strokeRect(L, T, W - L - R, H - T - B);
  if (lo < 0 && hi > 0) { g.beginPath(); g.moveTo(L, Y(0)); g.lineTo(W - R, Y(0)); g.stroke(); }
  g.fillStyle = "#555"; g.font = "10px sans-serif";
  g.fillText(hi.toPrecision(3), 2, T + 8); g.fillText(lo.toPrecision(3), 2, H - B);
  g.fillText(`${t0.toFixed(1)} s`, L, H - 4); g.fillText(`${tEnd.toFixed(1)} s`, W - R - 40, H - 4);
  p.series.forEach(([key, color], i) => {
    const k = view.ix[key];
    const style = i === 0 ? UNDER : OVER;
    g.save();
    g.beginPath(); g.rect(L, T, W - L - R, H - T - B); g.clip();
    g.strokeStyle = color; g.lineWidth = style.width;
    g.setLineDash(style.dash);
    g.beginPath();
    let started = false;
    for (const r of shown) {
      const v = r[k];
      if (v === null) { started = false; continue; }
      if (started) g.lineTo(X(r[it]), Y(v)); else { g.moveTo(X(r[it]), Y(v)); started = true; }
    }
    g.stroke();
    g.restore();
  });
  let lx = W - R - 10;
  for (const [, color, label] of [...p.series].reverse()) {
    g.fillStyle = color; g.font = "11px sans-serif";
    lx -= g.measureText(label).width + 12;
    g.fillText(label, lx, 13);
  }
}

// ---- status panel -------------------------------------------------------------------------
function text(id, v) { document.getElementById(id).textContent = v; }
function fmt(v, d) { return v === null || v === undefined ? "-" : v.toFixed(d); }

// RESET_INFO (view.py's reset_state): the last reset, and whether the board kept its pose.
function resetText(rs) {
  if (!rs) return "-";
  if (rs.cause === "POWER_ON" && rs.count === 0) return "none since power-on";
  const kept = rs.pose_lost ? "POSE LOST: orders refused until the position is set"
    : `pose kept, radius widened ${rs.widened_mm} mm`;
  return `${rs.cause}, ${rs.count} since power-on; ${kept}`;
}

function updatePanel() {
  const r = view.last;
  const st = view.state;
  if (r) {
    text("time", `t = ${r.t_s.toFixed(3)} s`);
    text("ex", fmt(r.est_x_mm, 1)); text("ey", fmt(r.est_y_mm, 1)); text("eh", fmt(r.est_heading_deg, 2));
    text("tx", fmt(r.x_mm, 1)); text("ty", fmt(r.y_mm, 1)); text("th", fmt(r.heading_deg, 2));
    text("radius", fmt(r.radius_mm, 0));
    const os = r.order_state === null ? "-" : (view.info.order_states[r.order_state] || r.order_state);
    text("order_state", os);
    const status = r.status || 0;
    for (const [name, bit] of view.info.status_bits) {
      const el = document.getElementById(`bit_${name}`);
      el.classList.toggle("on", (status & bit) !== 0);
    }
  }
  // The last order that ended; before the first one ends, whether one is under way.
  text("outcome", st.outcome || (st.orders ? "under way" : "none yet"));
  text("orders", st.orders ? `(${st.orders} ${st.orders === 1 ? "order" : "orders"} so far)` : "");
  text("message", performance.now() < view.noticeUntil ? view.notice : (st.message || ""));
  const m = st.match;
  text("match", !m ? "-" : `${m.paused ? "PAUSED" : "running"}, ${m.pending} pending,` +
    ` braking ${m.braking_mm} mm, scale ${m.scale_percent} %, ${m.lidar.length} lidar hits`);
  text("reset", resetText(st.reset));
  document.getElementById("reset").classList.toggle("lost", !!(st.reset && st.reset.pose_lost));
  const target = st.target || view.pendingTarget;
  text("target", target ? `(${target[0].toFixed(0)}, ${target[1].toFixed(0)})` : "none");
  document.getElementById("play").textContent = st.paused ? "play" : "pause";
  for (const b of document.querySelectorAll(".speed")) {
    b.classList.toggle("on", Number(b.dataset.speed) === st.speed);
  }
}

function setup(info, access) {
  view.info = info;
  view.access = access;
  info.fields.forEach((n, i) => { view.ix[n] = i; });
  text("kind", { sim: "simulator", board: "board", replay: "replay" }[info.kind] || info.kind);
  text("mode", access.mode);
  document.getElementById("mode").classList.toggle("drive", access.drive);
  fieldCanvas.classList.toggle("drive", access.drive);
  document.getElementById("play").disabled = !access.commands;
  document.getElementById("truerow").style.display = info.truth ? "" : "none";
  document.getElementById("hint").textContent = access.drive ?
    "click on the field: GOTO there" : "clicks on the field send nothing here";
  const bits = document.getElementById("bits");
  bits.innerHTML = "";
  for (const [name] of info.status_bits) {
    const el = document.createElement("span");
    el.className = "bit" + (/^(PB_|CHOC)/.test(name) ? " bad" : "");
    el.id = `bit_${name}`;
    el.textContent = name;
    bits.appendChild(el);
  }
  const sp = document.getElementById("speeds");
  sp.innerHTML = "speed ";
  for (const s of info.speeds) {
    const b = document.createElement("button");
    b.type = "button"; b.className = "speed"; b.dataset.speed = s; b.textContent = `x${s}`;
    b.onclick = () => send({ type: "speed", speed: s });
    b.disabled = !access.commands;
    sp.appendChild(b);
  }
  drawScene();
}

function onRows(msg) {
  view.state = msg.state;
  for (const r of msg.rows) {
    const o = rowObject(r);
    if (view.last && o.t_s < view.last.t_s) { // a replay started again: so do the paths
      view.rows = [];
      view.estPath = [];
      view.truePath = [];
    }
    view.rows.push(r);
    view.received += 1;
    if (o.est_x_mm !== null) view.estPath.push([o.est_x_mm, o.est_y_mm]);
    if (o.x_mm !== null) view.truePath.push([o.x_mm, o.y_mm]);
    view.last = o;
  }
  if (view.rows.length > HISTORY_MAX) view.rows.splice(0, view.rows.length - HISTORY_MAX);
  if (view.estPath.length > PATH_MAX) view.estPath.splice(0, view.estPath.length - PATH_MAX);
  if (view.truePath.length > PATH_MAX) view.truePath.splice(0, view.truePath.length - PATH_MAX);
  if (msg.state.target) view.pendingTarget = null;
}

function send(msg) {
  view.sent.push(msg);
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(msg));
}

fieldCanvas.addEventListener("click", (ev) => {
  if (!view.info || !view.access.drive) return;
  const rect = fieldCanvas.getBoundingClientRect();
  const px = (ev.clientX - rect.left) * fieldCanvas.width / rect.width;
  const py = (ev.clientY - rect.top) * fieldCanvas.height / rect.height;
  const [x, y] = toField(px, py);
  view.pendingTarget = [Math.round(x), Math.round(y)];
  send({ type: "goto", x: Math.round(x), y: Math.round(y) });
});

document.getElementById("play").onclick = () => send({ type: "pause", paused: !view.state.paused });

// The token of this run comes in the page's address (asserv view prints it) and goes with the
// stream's: without it the server lets the page watch, on loopback only, and send nothing.
function connect() {
  const token = new URLSearchParams(location.search).get("token");
  const query = token === null ? "" : `?token=${encodeURIComponent(token)}`;
  ws = new WebSocket(`ws://${location.host}/ws${query}`);
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "hello") setup(msg.info, msg.access);
    else if (msg.type === "rows") onRows(msg);
    else if (msg.type === "refused") {
      view.refused.push(msg.why);
      view.notice = `refused: ${msg.why}`;
      view.noticeUntil = performance.now() + 5000;
    }
  };
  ws.onclose = () => { text("kind", "disconnected: is asserv view still running?"); };
}

function frame() {
  if (view.info) {
    drawScene();
    for (const p of PLOTS) drawPlot(p);
    updatePanel();
  }
  requestAnimationFrame(frame);
}

connect();
requestAnimationFrame(frame);
