"""The interactive replay on a counterexample's card: a canvas, a time slider and play/pause.

:func:`replay_html` embeds a case's replay data (:func:`pytest_avscenario.sim.replay.replay_data`,
kept as ``cases/<test>-<hash>.replay.json``) in the card page with a small inline script: no
network, no external library, so a card opened from a CI artifact or an e-mail works as is.
The replay starts at the first violation and draws what the annotated still shows: the road,
every agent labelled with its name and speed, a velocity arrow per agent, the critical agent
ringed, a scale bar, and beside the picture the frame's metric values (the lines of
:func:`pytest_avscenario.sim.replay.frame_lines`). ``card.html#t=1.5`` opens it at 1.5 s.

For automated checks the replay's element carries ``data-frame``, ``data-t`` (the shown
time, 2 decimals) and ``data-draws`` (how many times the canvas was drawn). Nothing here
imports the simulator or pytest.
"""

from __future__ import annotations

import html
import json
from typing import Any, Mapping

__all__ = ["replay_html", "REPLAY_CSS", "REPLAY_JS"]

REPLAY_CSS = """
.replay { margin: .6em 0 1.2em; }
.replay canvas { display: block; max-width: 100%; height: auto; border: 1px solid #ccc; background: #607f56; }
.replay .controls { display: flex; align-items: center; gap: .7em; margin: .4em 0; max-width: 820px; }
.replay .controls input[type=range] { flex: 1; }
.replay .controls output { font-variant-numeric: tabular-nums; min-width: 7em; }
.replay pre.values { margin: .3em 0; max-width: 800px; }
"""

# ES5-level JavaScript on purpose: no build step, and old CI artifact viewers run it too.
REPLAY_JS = r"""
(function (id) {
  var root = document.getElementById(id);
  var D = JSON.parse(document.getElementById(id + "-data").textContent);
  var canvas = root.querySelector("canvas"), ctx = canvas.getContext("2d");
  var slider = root.querySelector("input[type=range]"), out = root.querySelector("output");
  var play = root.querySelector("button.play"), toFirst = root.querySelector("button.first");
  var valuesBox = root.querySelector("pre.values");
  var W = canvas.width, H = canvas.height, S = D.view.scale, N;
  var COLOURS = {ego: "rgb(60,200,80)", car: "rgb(90,150,230)", bus: "rgb(250,190,20)",
                 parked: "rgb(150,150,160)", pedestrian: "rgb(230,60,200)"};
  var HIGHLIGHT = "rgb(255,150,0)", INK = "rgb(25,25,28)", DARK = "rgb(35,35,40)";
  function undelta(s, scale) {  // first value + differences; [item, count] is a run
    var o = [], acc = 0;
    for (var i = 0; i < s.length; i++) {
      var run = Array.isArray(s[i]), d = run ? s[i][0] : s[i], n = run ? s[i][1] : 1;
      for (var j = 0; j < n; j++) {
        if (d === null) { o.push(null); } else { acc += d; o.push(acc / scale); }
      }
    }
    return o;
  }
  function frames(a, s, scale) {  // a series over the agent's frames k0 .. -> every frame
    var o = [], body = undelta(s, scale), i;
    for (i = 0; i < N; i++) o.push(i >= a.k0 && i - a.k0 < body.length ? body[i - a.k0] : null);
    return o;
  }
  D.t = undelta(D.t, 100);
  N = D.t.length;
  var agents = D.agents.map(function (a) {
    return {name: a.name, kind: a.kind, L: a.L, W: a.W, crash: a.crash, arm: a.arm || [],
            x: frames(a, a.x, 100), y: frames(a, a.y, 100), h: frames(a, a.h, 1), v: frames(a, a.v, 10)};
  });
  var V = {};
  Object.keys(D.values || {}).forEach(function (key) {
    V[key] = Array.isArray(D.values[key]) ? undelta(D.values[key], 100) : D.values[key];
  });
  var RT = {};
  Object.keys(D.rho_t || {}).forEach(function (key) { RT[key] = undelta(D.rho_t[key], 100); });
  var road = D.road || {lanes: [], boxes: [], crosswalks: [], stop_lines: []};
  var lanes = road.lanes.map(function (l) {
    var pts = [], x = 0, y = 0;  // decimetres, x and y each as first value + differences
    for (var i = 0; i + 1 < l.p.length; i += 2) { x += l.p[i]; y += l.p[i + 1]; pts.push([x / 10, y / 10]); }
    return {w: l.w, park: l.park, lines: l.lines, pts: pts};
  });
  var cx = 0, cy = 0, lastEgo = null;
  function centre(k) {
    var e = agents[0], here = e.x[k] !== null;
    if (here) lastEgo = [e.x[k], e.y[k]];
    var ex = here ? e.x[k] : (lastEgo ? lastEgo[0] : 0), ey = here ? e.y[k] : (lastEgo ? lastEgo[1] : 0);
    cx = D.view.cx !== null ? D.view.cx : ex + D.view.ahead;
    cy = D.view.cy !== null ? D.view.cy : ey;
  }
  function P(x, y) { return [(x - cx) * S + W / 2, H / 2 - (y - cy) * S]; }
  function path(pts, close) {
    ctx.beginPath();
    for (var i = 0; i < pts.length; i++) {
      var q = P(pts[i][0], pts[i][1]);
      if (i === 0) ctx.moveTo(q[0], q[1]); else ctx.lineTo(q[0], q[1]);
    }
    if (close) ctx.closePath();
  }
  function offset(pts, r) {  // the polyline r metres to the left
    var o = [];
    for (var i = 0; i < pts.length; i++) {
      var a = pts[Math.max(0, i - 1)], b = pts[Math.min(pts.length - 1, i + 1)];
      var dx = b[0] - a[0], dy = b[1] - a[1], n = Math.sqrt(dx * dx + dy * dy) || 1;
      o.push([pts[i][0] - dy / n * r, pts[i][1] + dx / n * r]);
    }
    return o;
  }
  function drawRoad() {
    ctx.fillStyle = "rgb(96,128,86)";
    ctx.fillRect(0, 0, W, H);
    ctx.fillStyle = "rgb(72,72,76)";
    road.boxes.forEach(function (b) {
      path([[b[0] - b[2], b[1] - b[2]], [b[0] + b[2], b[1] - b[2]], [b[0] + b[2], b[1] + b[2]],
            [b[0] - b[2], b[1] + b[2]]], true);
      ctx.fill();
    });
    ctx.lineCap = "butt"; ctx.lineJoin = "round";
    lanes.forEach(function (l) {
      ctx.strokeStyle = l.park ? "rgb(92,92,98)" : "rgb(72,72,76)";
      ctx.lineWidth = l.w * S;
      path(l.pts, false);
      ctx.stroke();
    });
    ctx.strokeStyle = "rgb(240,240,240)";
    ctx.lineWidth = Math.max(1, 0.15 * S);
    lanes.forEach(function (l) {
      [[0, l.w / 2], [1, -l.w / 2]].forEach(function (side) {
        var kind = l.lines[side[0]];
        if (!kind) return;
        ctx.setLineDash(kind === 1 ? [3 * S, 4.3 * S] : []);
        path(offset(l.pts, side[1]), false);
        ctx.stroke();
      });
    });
    ctx.setLineDash([]);
    ctx.fillStyle = "rgb(240,240,240)";
    road.crosswalks.forEach(function (c) {
      var ax = c[0], ay = c[1], dx = c[2] - ax, dy = c[3] - ay, len = Math.sqrt(dx * dx + dy * dy) || 1;
      var ux = dx / len, uy = dy / len, nx = -uy * c[4] / 2, ny = ux * c[4] / 2;
      for (var k = 0; k < len - 0.3; k += 1.2) {
        var k0 = k + 0.3, k1 = Math.min(k + 0.9, len);
        path([[ax + ux * k0 + nx, ay + uy * k0 + ny], [ax + ux * k1 + nx, ay + uy * k1 + ny],
              [ax + ux * k1 - nx, ay + uy * k1 - ny], [ax + ux * k0 - nx, ay + uy * k0 - ny]], true);
        ctx.fill();
      }
    });
    ctx.strokeStyle = "rgb(240,240,240)";
    ctx.lineWidth = Math.max(2, 0.4 * S);
    road.stop_lines.forEach(function (s) { path([[s[0], s[1]], [s[2], s[3]]], false); ctx.stroke(); });
  }
  function fmt(v, d) { return v === null ? "\u2014" : v.toFixed(d); }
  function signed(v) { return (v >= 0 ? "+" : "") + v.toFixed(2); }
  function lines(k) {  // the same lines as sim.replay.frame_lines
    var mark = (k === D.first && D.first_kind !== "moment") ? " \u2014 first " + D.first_kind : "";
    var o = ["t = " + D.t[k].toFixed(2) + " s" + mark];
    if (D.critical && V.d) {
      var d = V.d[k], ttc = V.ttc[k];
      var ttcText = d === null ? "\u2014" : (ttc === null ? "\u221e" : ttc.toFixed(2) + " s");
      o.push(D.critical + ": distance " + (d === null ? "\u2014" : d.toFixed(2) + " m") + ", gap " +
             (V.gap[k] === null ? "\u2014" : V.gap[k].toFixed(2) + " m") + ", TTC " + ttcText);
    }
    D.violations.forEach(function (v) {
      var per = RT[v.metric];
      var now = per && per[k] !== null ? "\u03c1(t) " + signed(per[k]) + ", " : "";
      var when = v.t === null ? "" : ", first at " + v.t.toFixed(2) + " s";
      o.push(v.metric + ": " + now + "run \u03c1 " + (v.rho === null ? "\u2014" : signed(v.rho)) + when);
    });
    return o;
  }
  function arrow(a, b) {
    ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke();
    var dx = b[0] - a[0], dy = b[1] - a[1], n = Math.sqrt(dx * dx + dy * dy);
    if (n < 4) return;
    var ux = dx / n, uy = dy / n, head = Math.min(10, n / 2);
    ctx.beginPath();
    ctx.moveTo(b[0], b[1]);
    ctx.lineTo(b[0] - ux * head - uy * head * 0.6, b[1] - uy * head + ux * head * 0.6);
    ctx.lineTo(b[0] - ux * head + uy * head * 0.6, b[1] - uy * head - ux * head * 0.6);
    ctx.closePath(); ctx.fill();
  }
  function drawAgents(k) {
    var order = agents.map(function (a, i) { return i; }).sort(function (i, j) {
      return (agents[i].kind === "pedestrian") - (agents[j].kind === "pedestrian") || i - j;
    });
    order.forEach(function (i) {
      var a = agents[i];
      if (a.x[k] === null) return;
      var x = a.x[k], y = a.y[k], h = a.h[k] * Math.PI / 180, c = Math.cos(h), s = Math.sin(h);
      var crashed = a.crash !== null && k >= a.crash;
      ctx.fillStyle = COLOURS[a.kind] || COLOURS.car;
      ctx.strokeStyle = crashed ? "rgb(255,40,40)" : "rgb(20,20,20)";
      ctx.lineWidth = crashed ? 3 : 1;
      if (a.kind === "pedestrian") {
        var q = P(x, y);
        ctx.beginPath(); ctx.arc(q[0], q[1], Math.max(4, 0.5 * S), 0, 2 * Math.PI);
        ctx.fill(); ctx.stroke();
        return;
      }
      var L = a.L / 2, B = a.W / 2;
      path([[x + c * L - s * B, y + s * L + c * B], [x + c * L + s * B, y + s * L - c * B],
            [x - c * L + s * B, y - s * L - c * B], [x - c * L - s * B, y - s * L + c * B]], true);
      ctx.fill(); ctx.stroke();
      ctx.strokeStyle = "rgb(30,30,30)"; ctx.lineWidth = Math.max(1, 0.3 * S);
      var f = a.L / 2 - 1.2, wb = a.W / 2.5;
      path([[x + c * f - s * wb, y + s * f + c * wb], [x + c * f + s * wb, y + s * f - c * wb]], false);
      ctx.stroke();
      if (a.arm.indexOf(k) >= 0) {
        var ar = P(x + c * (a.L / 2 - 2) - s * (a.W / 2 + 0.8), y + s * (a.L / 2 - 2) + c * (a.W / 2 + 0.8));
        ctx.fillStyle = "rgb(255,40,40)";
        ctx.beginPath(); ctx.arc(ar[0], ar[1], Math.max(3, 0.6 * S), 0, 2 * Math.PI); ctx.fill();
      }
    });
    agents.forEach(function (a) {  // the critical agent's ring and everybody's velocity arrow
      if (a.x[k] === null) return;
      var q = P(a.x[k], a.y[k]), h = a.h[k] * Math.PI / 180, v = a.v[k] || 0;
      if (a.name === D.critical) {
        ctx.strokeStyle = HIGHLIGHT; ctx.lineWidth = 3;
        ctx.beginPath(); ctx.arc(q[0], q[1], Math.max(10, (Math.max(a.L, a.W) / 2 + 1.2) * S), 0, 2 * Math.PI);
        ctx.stroke();
      }
      if (Math.abs(v) > 0.05) {
        var len = v * D.arrow_s;
        ctx.strokeStyle = "white"; ctx.fillStyle = "white"; ctx.lineWidth = 2;
        arrow(q, P(a.x[k] + Math.cos(h) * len, a.y[k] + Math.sin(h) * len));
      }
    });
    ctx.font = "bold 13px system-ui, sans-serif";
    ctx.textBaseline = "middle";
    var taken = [];
    var ids = agents.map(function (a, i) { return i; }).sort(function (i, j) {
      return (agents[i].name !== D.critical) - (agents[j].name !== D.critical) || i - j;
    });
    ids.forEach(function (i) {
      var a = agents[i];
      if (a.x[k] === null) return;
      var hot = a.name === D.critical, q = P(a.x[k], a.y[k]);
      var text = a.name + " " + (a.v[k] === null ? 0 : a.v[k]).toFixed(1) + " m/s" +
        (q[0] < 0 || q[0] >= W || q[1] < 0 || q[1] >= H ? " (out of view)" : "");
      var w = ctx.measureText(text).width + 6, h = 17, off = (Math.max(a.L, a.W) / 2 + 1.5) * S + 4;
      var r = {x: q[0] - w / 2, y: i === 0 ? q[1] + off : q[1] - off - h, w: w, h: h};
      var step = i === 0 ? h + 2 : -(h + 2);
      for (var n = 0; n < 8 && taken.some(function (t) {
        return r.x < t.x + t.w && t.x < r.x + r.w && r.y < t.y + t.h && t.y < r.y + r.h;
      }); n++) r.y += step;
      r.x = Math.min(Math.max(r.x, 0), W - r.w); r.y = Math.min(Math.max(r.y, 0), H - r.h);
      taken.push(r);
      ctx.strokeStyle = hot ? HIGHLIGHT : DARK; ctx.lineWidth = 1;
      ctx.beginPath(); ctx.moveTo(q[0], q[1]);
      ctx.lineTo(Math.min(Math.max(q[0], r.x), r.x + r.w), r.y > q[1] ? r.y : r.y + r.h); ctx.stroke();
      ctx.fillStyle = hot ? HIGHLIGHT : DARK;
      ctx.fillRect(r.x, r.y, r.w, r.h);
      ctx.fillStyle = hot ? INK : "rgb(250,250,250)";
      ctx.fillText(text, r.x + 3, r.y + h / 2 + 1);
    });
  }
  function drawScale() {
    var target = W / S / 6, metres = 1;
    [1, 10, 100, 1000].forEach(function (d) { [1, 2, 5].forEach(function (m) { if (m * d <= target) metres = m * d; }); });
    var bar = metres * S, x0 = 12, y0 = H - 14;
    var text = metres + " m   arrows: " + D.arrow_s + " s of travel";
    ctx.font = "12px system-ui, sans-serif";
    ctx.fillStyle = DARK;
    ctx.fillRect(x0 - 6, y0 - 26, Math.max(bar, ctx.measureText(text).width) + 12, 34);
    ctx.fillStyle = "rgb(250,250,250)"; ctx.strokeStyle = "rgb(250,250,250)"; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x0 + bar, y0); ctx.stroke();
    ctx.lineWidth = 2;
    [x0, x0 + bar].forEach(function (x) { ctx.beginPath(); ctx.moveTo(x, y0 - 5); ctx.lineTo(x, y0 + 3); ctx.stroke(); });
    ctx.textBaseline = "alphabetic";
    ctx.fillText(text, x0, y0 - 10);
  }
  var draws = 0;
  function draw(k) {
    k = Math.max(0, Math.min(N - 1, k | 0));
    centre(k);
    drawRoad();
    drawAgents(k);
    drawScale();
    var text = lines(k);
    out.textContent = text[0];
    valuesBox.textContent = text.slice(1).join("\n");
    draws += 1;
    root.setAttribute("data-frame", String(k));
    root.setAttribute("data-t", D.t[k].toFixed(2));
    root.setAttribute("data-draws", String(draws));
  }
  var timer = null;
  function stop() { if (timer !== null) { clearInterval(timer); timer = null; } play.textContent = "\u25b6 play"; }
  play.addEventListener("click", function () {
    if (timer !== null) { stop(); return; }
    if (+slider.value >= N - 1) { slider.value = 0; draw(0); }
    play.textContent = "\u275a\u275a pause";
    var dt = N > 1 ? (D.t[N - 1] - D.t[0]) / (N - 1) : 0.2;
    timer = setInterval(function () {
      var k = +slider.value + 1;
      if (k >= N) { stop(); return; }
      slider.value = k; draw(k);
    }, Math.max(20, dt * 1000));
  });
  toFirst.addEventListener("click", function () { stop(); slider.value = D.first; draw(D.first); });
  slider.addEventListener("input", function () { draw(+slider.value); });
  function fromHash() {
    var m = /(?:^|[#&])t=([0-9.]+)/.exec(window.location.hash);
    if (!m) return false;
    var t = parseFloat(m[1]), best = 0;
    for (var i = 1; i < N; i++) if (Math.abs(D.t[i] - t) < Math.abs(D.t[best] - t)) best = i;
    slider.value = best;
    slider.dispatchEvent(new Event("input"));
    return true;
  }
  window.addEventListener("hashchange", fromHash);
  if (!fromHash()) draw(D.first);
})(%(id)s);
"""


def _json_for_script(data: Mapping[str, Any]) -> str:
    # "<" escaped: no "</script>" (nor "<!--") inside a name can end the data block early
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def replay_html(data: Mapping[str, Any], element_id: str = "replay") -> str:
    """The replay section of a card page for replay ``data``: canvas, slider, play/pause,
    the frame's metric values, the data itself and the script, self-contained."""
    eid = html.escape(element_id, quote=True)
    n = sum(item[1] if isinstance(item, list) else 1 for item in data["t"])  # runs: [item, count]
    first = int(data["first"])
    size = data["view"]["size"]
    what = {"violation": "first violation", "contact": "first contact"}.get(data.get("first_kind"), "moment shown")
    critical = data.get("critical")
    legend = (f"Starts at the {what} (t = {data['first_t']:.2f} s). Arrows: where each agent is "
              f"{data.get('arrow_s', 1.0):g} s later at its current speed; "
              + (f"ringed: {html.escape(critical)}, the critical agent; " if critical else "")
              + "red outline: crashed. Drag the slider or use ← → on it; "
              f"<code>#t=…</code> on the page's address opens the replay at that time.")
    return "\n".join([
        f"<style>{REPLAY_CSS}</style>",
        f"<section class='replay' id='{eid}' data-frame='{first}' data-draws='0'>",
        f"<canvas width='{int(size[0])}' height='{int(size[1])}' "
        f"aria-label='bird&#x27;s-eye replay of the run'></canvas>",
        "<div class='controls'>",
        "<button type='button' class='play'>&#9654; play</button>",
        f"<input type='range' min='0' max='{n - 1}' step='1' value='{first}' list='{eid}-marks' "
        f"aria-label='time'>",
        f"<datalist id='{eid}-marks'><option value='{first}'></option></datalist>",
        f"<output>t = {data['first_t']:.2f} s</output>",
        f"<button type='button' class='first'>{html.escape(what)}</button>",
        "</div>",
        "<pre class='values'></pre>",
        f"<p class='meta'>{legend}</p>",
        f"<script type='application/json' id='{eid}-data'>{_json_for_script(data)}</script>",
        f"<script>{REPLAY_JS % {'id': json.dumps(element_id)}}</script>",
        "</section>",
    ])
