"""The card's player: a counterexample's recording on a canvas, with a time slider and play/pause.

:func:`player_html` embeds a case's recording (:func:`pytest_avscenario.report.recording.recording_data`,
a clip of :mod:`pytest_avscenario.sim.clip`, kept as ``cases/<test>-<hash>.replay.json`` until
the card takes it in) in the card page with a small player script — the report's shared
``cases/replay-<hash>.js`` (:func:`player_file`), or inline for a page made on its own: no
network, no external library, so a report opened from a CI artifact works as is. (The file
names and the page's ``replay`` ids are kept as earlier reports wrote them; in the code,
"replay" means the replay database only.)
The player starts at the first violation and draws what the annotated still shows: the road,
every agent labelled with its name and speed, a velocity arrow per agent, the critical agent
ringed, a scale bar, and beside the picture the frame's metric values and the ego's decision
in force (the lines of :func:`pytest_avscenario.sim.clip.frame_lines`); the slider has a
tick where the decision changes. ``card.html#t=1.5`` opens it at 1.5 s.

For automated checks the player's element carries ``data-frame``, ``data-t`` (the shown
time, 2 decimals), ``data-draws`` (how many times the canvas was drawn) and ``data-labels``
(JSON: per agent name its label's ``box`` and its footprint's ``car`` box on the canvas,
``[left, top, width, height]`` [px]; labels are placed as the still places them,
:func:`pytest_avscenario.sim.render._place_labels`). Nothing here
imports the simulator or pytest.
"""

from __future__ import annotations

import html
import json
import re
from typing import Any, Mapping

__all__ = ["player_html", "player_file", "PLAYER_CSS", "PLAYER_JS"]

PLAYER_CSS = """
.replay { margin: .6em 0 1.2em; }
.replay canvas { display: block; max-width: 100%; height: auto; border: 1px solid #ccc; background: #607f56; }
.replay .controls { display: flex; align-items: center; gap: .7em; margin: .4em 0; max-width: 820px; }
.replay .controls input[type=range] { flex: 1; }
.replay .controls output { font-variant-numeric: tabular-nums; min-width: 7em; }
.replay pre.values { margin: .3em 0; max-width: 800px; }
"""

# ES5-level JavaScript on purpose: no build step, and old CI artifact viewers run it too. It is
# shipped without indentation and comments: in the report, once per report as
# cases/replay-<hash>.js (player_file); inline in a page made on its own.
PLAYER_JS = r"""
function avsReplay(id) {
  var root = document.getElementById(id), D = JSON.parse(document.getElementById(id + "-data").textContent);
  var canvas = root.querySelector("canvas"), c = canvas.getContext("2d");
  var slider = root.querySelector("input"), out = root.querySelector("output");
  var play = root.querySelector(".play"), box = root.querySelector("pre");
  var W = canvas.width, H = canvas.height, S = D.view.scale, PI2 = 2 * Math.PI;
  var GREY = "rgb(240,240,240)", HOT = "rgb(255,150,0)", DARK = "rgb(35,35,40)", RED = "rgb(255,40,40)";
  var COLOURS = {ego: "rgb(60,200,80)", car: "rgb(90,150,230)", truck: "rgb(200,110,60)", bus: "rgb(250,190,20)",
                 parked: "rgb(150,150,160)", pedestrian: "rgb(230,60,200)"};
  function undelta(s, scale) {  // first value + differences; [item, count] is a run of items
    var o = [], acc = 0;
    s.forEach(function (it) {
      var run = Array.isArray(it), d = run ? it[0] : it;
      for (var j = 0; j < (run ? it[1] : 1); j++) o.push(d === null ? null : (acc += d) / scale);
    });
    return o;
  }
  function obj(m, f) { var o = {}; Object.keys(m || {}).forEach(function (k) { o[k] = f(m[k]); }); return o; }
  var T = undelta(D.t, 100), N = T.length;
  var V = obj(D.values, function (v) { return Array.isArray(v) ? undelta(v, 100) : v; });
  var RT = obj(D.rho_t, function (v) { return undelta(v, 100); });
  var agents = D.agents.map(function (a) {
    function f(s, scale) {  // the agent's frames k0 .. spread over every frame
      var b = undelta(s, scale), o = [];
      for (var i = 0; i < N; i++) o.push(i >= a.k0 && i - a.k0 < b.length ? b[i - a.k0] : null);
      return o;
    }
    return {name: a.name, kind: a.kind, L: a.L, W: a.W, crash: a.crash, arm: a.arm || [],
            x: f(a.x, 100), y: f(a.y, 100), h: f(a.h, 180 / Math.PI), v: f(a.v, 10)};
  });
  var road = D.road || {lanes: [], boxes: [], crosswalks: [], stop_lines: []};
  var lanes = road.lanes.map(function (l) {  // [width, parking, left line, right line, points]
    var pts = [], x = 0, y = 0;  // decimetres, x and y each as first value + differences
    for (var i = 4; i + 1 < l.length; i += 2) pts.push([(x += l[i]) / 10, (y += l[i + 1]) / 10]);
    return {w: l[0], park: l[1], lines: [l[2], l[3]], pts: pts};
  });
  var cx = 0, cy = 0, ego = [0, 0];
  function P(x, y) { return [(x - cx) * S + W / 2, H / 2 - (y - cy) * S]; }
  function path(pts, close) {
    c.beginPath();
    pts.forEach(function (p, i) { var q = P(p[0], p[1]); c[i ? "lineTo" : "moveTo"](q[0], q[1]); });
    if (close) c.closePath();
  }
  function pen(colour, width, dash) { c.strokeStyle = colour; c.lineWidth = width; c.setLineDash(dash || []); }
  function seg(a, b) { c.beginPath(); c.moveTo(a[0], a[1]); c.lineTo(b[0], b[1]); c.stroke(); }
  function disc(q, r, fill) { c.beginPath(); c.arc(q[0], q[1], r, 0, PI2); if (fill) c.fill(); c.stroke(); }
  function offset(pts, r) {  // the polyline r metres to the left
    return pts.map(function (p, i) {
      var a = pts[Math.max(0, i - 1)], b = pts[Math.min(pts.length - 1, i + 1)];
      var dx = b[0] - a[0], dy = b[1] - a[1], n = Math.sqrt(dx * dx + dy * dy) || 1;
      return [p[0] - dy / n * r, p[1] + dx / n * r];
    });
  }
  function drawRoad() {
    c.fillStyle = "rgb(96,128,86)"; c.fillRect(0, 0, W, H);
    c.fillStyle = "rgb(72,72,76)";
    road.boxes.forEach(function (b) {
      var h = b[2];
      path([[b[0] - h, b[1] - h], [b[0] + h, b[1] - h], [b[0] + h, b[1] + h], [b[0] - h, b[1] + h]], true);
      c.fill();
    });
    c.lineCap = "butt"; c.lineJoin = "round";
    lanes.forEach(function (l) { pen(l.park ? "rgb(92,92,98)" : "rgb(72,72,76)", l.w * S); path(l.pts); c.stroke(); });
    lanes.forEach(function (l) {
      [l.w / 2, -l.w / 2].forEach(function (r, side) {
        var kind = l.lines[side];  // highway-env's line types: 0 none, 1 striped, else continuous
        if (!kind) return;
        pen(GREY, Math.max(1, 0.15 * S), kind === 1 ? [3 * S, 4.3 * S] : []);
        path(offset(l.pts, r)); c.stroke();
      });
    });
    pen(GREY, Math.max(2, 0.4 * S));
    c.fillStyle = GREY;
    road.crosswalks.forEach(function (w) {
      var dx = w[2] - w[0], dy = w[3] - w[1], len = Math.sqrt(dx * dx + dy * dy) || 1;
      var ux = dx / len, uy = dy / len, nx = -uy * w[4] / 2, ny = ux * w[4] / 2;
      for (var k = 0.3; k < len; k += 1.2) {
        var e = Math.min(k + 0.6, len), A = [w[0] + ux * k, w[1] + uy * k], B = [w[0] + ux * e, w[1] + uy * e];
        path([[A[0] + nx, A[1] + ny], [B[0] + nx, B[1] + ny], [B[0] - nx, B[1] - ny], [A[0] - nx, A[1] - ny]], true);
        c.fill();
      }
    });
    road.stop_lines.concat(road.lane_ends || []).forEach(function (s) { path([[s[0], s[1]], [s[2], s[3]]]); c.stroke(); });
  }
  var LIGHTS = ["rgb(40,200,80)", "rgb(255,185,0)", "rgb(230,30,30)"];  // green, amber, red
  function drawLights(k) {  // each light's state at frame k: bars at its stop positions, its head
    (D.lights || []).forEach(function (l) {
      var code = 0;
      l.at.forEach(function (a) { if (a[0] <= k) code = a[1]; });
      pen(LIGHTS[code], Math.max(3, 0.6 * S));
      l.stops.forEach(function (s) { path([[s[0], s[1]], [s[2], s[3]]]); c.stroke(); });
      var q = P(l.x, l.y), r = Math.max(5, 1.2 * S);
      c.fillStyle = "rgb(25,25,25)"; c.fillRect(q[0] - r - 2, q[1] - r - 2, 2 * r + 4, 2 * r + 4);
      c.fillStyle = LIGHTS[code]; pen(LIGHTS[code], 1); disc(q, r, true);
    });
  }
  function decision(k) {  // [since, label] in force at frame k, as sim.clip.decision_at
    var now = null, cs = Math.round(T[k] * 100), at = D.decisions ? D.decisions.at : [];
    for (var i = 0; i < at.length && at[i][0] <= cs; i++) now = [at[i][0] / 100, D.decisions.labels[at[i][1]]];
    return now;
  }
  function signed(v) { return (v >= 0 ? "+" : "") + v.toFixed(2); }
  function lines(k) {  // the same lines as sim.clip.frame_lines
    var mark = k === D.first && D.first_kind !== "moment" ? " \u2014 first " + D.first_kind : "";
    var o = ["t = " + T[k].toFixed(2) + " s" + mark], dash = "\u2014";
    if (D.critical && V.d) {
      var d = V.d[k], g = V.gap[k], ttc = V.ttc[k];
      o.push(D.critical + ": distance " + (d === null ? dash : d.toFixed(2) + " m") + ", gap " +
             (g === null ? dash : g.toFixed(2) + " m") + ", TTC " +
             (d === null ? dash : ttc === null ? "\u221e" : ttc.toFixed(2) + " s"));
    }
    var made = decision(k);
    if (made) o.push(agents[0].name + (D.decisions.source === "action" ? " decision: " : " reason: ") + made[1] +
                     " (since " + made[0].toFixed(2) + " s)");
    D.violations.forEach(function (v) {
      var per = RT[v.metric];
      o.push(v.metric + ": " + (per && per[k] !== null ? "\u03c1(t) " + signed(per[k]) + ", " : "") + "run \u03c1 " +
             (v.rho === null ? dash : (v.rho >= 0 ? "+" : "") + v.rho.toFixed(3)) + (v.t === null ? "" : ", first at " + v.t.toFixed(2) + " s") +
             (D["case"] ? " (" + D["case"] + " case)" : ""));
    });
    return o;
  }
  function arrow(a, b) {
    seg(a, b);
    var dx = b[0] - a[0], dy = b[1] - a[1], n = Math.sqrt(dx * dx + dy * dy), h = Math.min(10, n / 2);
    if (n < 4) return;
    dx /= n; dy /= n;
    c.beginPath(); c.moveTo(b[0], b[1]);
    c.lineTo(b[0] - dx * h - dy * h * 0.6, b[1] - dy * h + dx * h * 0.6);
    c.lineTo(b[0] - dx * h + dy * h * 0.6, b[1] - dy * h - dx * h * 0.6);
    c.fill();
  }
  function order(key) {
    return agents.map(function (a, i) { return i; }).sort(function (i, j) { return key(agents[i]) - key(agents[j]) || i - j; });
  }
  function drawAgents(k) {
    order(function (a) { return a.kind === "pedestrian"; }).forEach(function (i) {
      var a = agents[i], x = a.x[k], y = a.y[k], cs = Math.cos(a.h[k]), sn = Math.sin(a.h[k]);
      if (x === null) return;
      var crashed = a.crash !== null && k >= a.crash;
      c.fillStyle = COLOURS[a.kind] || COLOURS.car;
      pen(crashed ? RED : "rgb(20,20,20)", crashed ? 3 : 1);
      if (a.kind === "pedestrian") return disc(P(x, y), Math.max(4, 0.5 * S), true);
      function at(l, w) { return [x + cs * l - sn * w, y + sn * l + cs * w]; }  // l ahead, w left of the centre
      var L = a.L / 2, B = a.W / 2;
      path([at(L, B), at(L, -B), at(-L, -B), at(-L, B)], true); c.fill(); c.stroke();
      pen("rgb(30,30,30)", Math.max(1, 0.3 * S));
      path([at(L - 1.2, a.W / 2.5), at(L - 1.2, -a.W / 2.5)]); c.stroke();  // the windscreen
      if (a.arm.indexOf(k) >= 0) { c.fillStyle = RED; pen(RED, 1); disc(P.apply(null, at(L - 2, B + 0.8)), Math.max(3, 0.6 * S), true); }
    });
    agents.forEach(function (a) {  // the critical agent's ring and everybody's velocity arrow
      if (a.x[k] === null) return;
      var q = P(a.x[k], a.y[k]), len = (a.v[k] || 0) * D.arrow_s;
      if (a.name === D.critical) { pen(HOT, 3); disc(q, Math.max(10, (Math.max(a.L, a.W) / 2 + 1.2) * S)); }
      if (Math.abs(len) > 0.05) {
        pen("white", 2); c.fillStyle = "white";
        arrow(q, P(a.x[k] + Math.cos(a.h[k]) * len, a.y[k] + Math.sin(a.h[k]) * len));
      }
    });
  }
  function overlap(a, b) {
    var w = Math.min(a.x + a.w, b.x + b.w) - Math.max(a.x, b.x), h = Math.min(a.y + a.h, b.y + b.h) - Math.max(a.y, b.y);
    return w > 0 && h > 0 ? w * h : 0;
  }
  function gap(a, b) {
    var dx = Math.max(b.x - (a.x + a.w), a.x - (b.x + b.w), 0), dy = Math.max(b.y - (a.y + a.h), a.y - (b.y + b.h), 0);
    return Math.sqrt(dx * dx + dy * dy);
  }
  function nearest(r, q) { return [Math.min(Math.max(q[0], r.x), r.x + r.w - 1), Math.min(Math.max(q[1], r.y), r.y + r.h - 1)]; }
  function crosses(a, b, r) {  // segment a-b through box r (Liang-Barsky), as the still's
    var dx = b[0] - a[0], dy = b[1] - a[1], t0 = 0, t1 = 1;
    var pq = [[-dx, a[0] - r.x], [dx, r.x + r.w - a[0]], [-dy, a[1] - r.y], [dy, r.y + r.h - a[1]]];
    for (var j = 0; j < 4; j++) {
      var p = pq[j][0], q = pq[j][1];
      if (p === 0) { if (q < 0) return false; continue; }
      if (p < 0) t0 = Math.max(t0, q / p); else t1 = Math.min(t1, q / p);
      if (t0 > t1) return false;
    }
    return true;
  }
  function footprint(a, k) {  // the pixel box around an agent's drawn footprint
    var q = P(a.x[k], a.y[k]);
    if (a.kind === "pedestrian") { var d = Math.max(4, 0.5 * S); return {x: q[0] - d, y: q[1] - d, w: 2 * d + 1, h: 2 * d + 1}; }
    var cs = Math.cos(a.h[k]), sn = Math.sin(a.h[k]), xs = [], ys = [];
    [[1, 1], [1, -1], [-1, -1], [-1, 1]].forEach(function (f) {
      var p = P(a.x[k] + cs * f[0] * a.L / 2 - sn * f[1] * a.W / 2, a.y[k] + sn * f[0] * a.L / 2 + cs * f[1] * a.W / 2);
      xs.push(p[0]); ys.push(p[1]);
    });
    var x0 = Math.min.apply(null, xs), y0 = Math.min.apply(null, ys);
    return {x: x0, y: y0, w: Math.max.apply(null, xs) - x0 + 1, h: Math.max.apply(null, ys) - y0 + 1};
  }
  var DIRS = [];
  for (var di = 0; di < 16; di++) DIRS.push([Math.sin(di * Math.PI / 8), -Math.cos(di * Math.PI / 8)]);
  function place(w, h, q, own, below, cars, taken, arrows) {  // as sim.render._place_labels
    var best = null, others = cars.filter(function (c) {  // its own footprint is within its own box
      return !(own.x <= c.x && own.y <= c.y && c.x + c.w <= own.x + own.w && c.y + c.h <= own.y + own.h);
    });
    var ocx = own.x + own.w / 2, ocy = own.y + own.h / 2;
    for (var d = 2; d <= 110; d += 10) {
      DIRS.forEach(function (u, j) {
        var ux = u[0], uy = below ? -u[1] : u[1];
        var t = Math.min(Math.abs(ux) > 1e-9 ? (d + (own.w + w) / 2) / Math.abs(ux) : Infinity,
                         Math.abs(uy) > 1e-9 ? (d + (own.h + h) / 2) / Math.abs(uy) : Infinity);
        var r = {x: Math.round(ocx + ux * t - w / 2), y: Math.round(ocy + uy * t - h / 2), w: w, h: h};
        if (r.x < 0 || r.y < 0 || r.x + w > W || r.y + h > H) return;
        var cost = 0, near = gap(r, own), end = nearest(r, q);
        others.forEach(function (c) { cost += 1e6 * overlap(r, c) + (crosses(q, end, c) ? 300 : 0); });
        taken.forEach(function (b) { cost += 1e6 * overlap(r, b); });
        cost += 1e3 * overlap(r, own);
        arrows.forEach(function (s) { if (crosses(s[0], s[1], r)) cost += 60; });
        if (others.length && Math.min.apply(null, others.map(function (c) { return gap(r, c); })) < near + 4) cost += 250;
        cost += 10 * near + j % 8;
        if (best === null || cost < best.cost) best = {cost: cost, r: r};
      });
      if (best !== null && best.cost < 10 * (d + 10)) break;
    }
    return best ? best.r : {x: Math.min(Math.max(ocx - w / 2, 0), W - w), y: Math.min(Math.max(own.y - h - 2, 0), H - h), w: w, h: h};
  }
  function drawLabels(k, taken) {  // as the still: beside its own car, off other cars and labels
    c.font = "bold 13px system-ui, sans-serif"; c.textBaseline = "middle";
    var e = agents[0], cars = [], arrows = [], todo = [];
    function far(a) { return e.x[k] === null ? 0 : Math.sqrt(Math.pow(a.x[k] - e.x[k], 2) + Math.pow(a.y[k] - e.y[k], 2)); }
    order(function (a) { return (a !== e) * 1e9 + (a.name !== D.critical) * 1e8 + (a.x[k] === null ? 0 : far(a)); }).forEach(function (i) {
      var a = agents[i];
      if (a.x[k] === null) return;
      var q = P(a.x[k], a.y[k]), out = q[0] < 0 || q[0] >= W || q[1] < 0 || q[1] >= H, own;
      if (out) { q = [Math.min(Math.max(q[0], 0), W - 1), Math.min(Math.max(q[1], 0), H - 1)]; own = {x: q[0], y: q[1], w: 0, h: 0}; }
      else { own = footprint(a, k); cars.push(own); }
      var at = own;
      if (a.name === D.critical && !out) {  // its label goes around its ring, not onto it
        var rr = Math.max(10, (Math.max(a.L, a.W) / 2 + 1.2) * S) + 2;
        at = {x: q[0] - rr, y: q[1] - rr, w: 2 * rr + 1, h: 2 * rr + 1};
        cars.push(at);
      }
      var len = (a.v[k] || 0) * D.arrow_s;
      if (Math.abs(len) > 0.05) arrows.push([P(a.x[k], a.y[k]), P(a.x[k] + Math.cos(a.h[k]) * len, a.y[k] + Math.sin(a.h[k]) * len)]);
      todo.push({a: a, q: q, own: own, at: at, i: i, text: a.name + " " + (a.v[k] || 0).toFixed(1) + " m/s" + (out ? " (out of view)" : "")});
    });
    var placed = {};
    todo.forEach(function (l) {
      l.r = place(Math.ceil(c.measureText(l.text).width) + 6, 17, l.q, l.at, l.i === 0, cars, taken, arrows);
      taken.push(l.r);
      placed[l.a.name] = {box: [l.r.x, l.r.y, l.r.w, l.r.h], car: [l.own.x, l.own.y, l.own.w, l.own.h]};
    });
    todo.forEach(function (l) { pen(l.a.name === D.critical ? HOT : DARK, 1); seg(l.q, nearest(l.r, l.q)); });
    todo.forEach(function (l) {  // the labels over every leader line
      var hot = l.a.name === D.critical, r = l.r;
      c.fillStyle = hot ? HOT : DARK; c.fillRect(r.x, r.y, r.w, r.h);
      c.fillStyle = hot ? "rgb(25,25,28)" : "rgb(250,250,250)"; c.fillText(l.text, r.x + 3, r.y + r.h / 2 + 1);
    });
    root.setAttribute("data-labels", JSON.stringify(placed));
  }
  function drawScale() {
    var m = 1, x0 = 12, y0 = H - 14;
    [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000].forEach(function (v) { if (v <= W / S / 6) m = v; });
    var text = m + " m   arrows: " + D.arrow_s + " s of travel";
    c.font = "12px system-ui, sans-serif"; c.textBaseline = "alphabetic";
    c.fillStyle = DARK; c.fillRect(x0 - 6, y0 - 26, Math.max(m * S, c.measureText(text).width) + 12, 34);
    pen("rgb(250,250,250)", 3); seg([x0, y0], [x0 + m * S, y0]);
    pen("rgb(250,250,250)", 2); seg([x0, y0 - 5], [x0, y0 + 3]); seg([x0 + m * S, y0 - 5], [x0 + m * S, y0 + 3]);
    c.fillStyle = "rgb(250,250,250)"; c.fillText(text, x0, y0 - 10);
    return {x: x0 - 6, y: y0 - 26, w: Math.max(m * S, c.measureText(text).width) + 12, h: 34};
  }
  var draws = 0, timer = null;
  function draw(k) {
    k = Math.max(0, Math.min(N - 1, k | 0));
    var e = agents[0];
    if (e.x[k] !== null) ego = [e.x[k], e.y[k]];
    var h = D.view.along && e.h[k] !== null ? e.h[k] : 0;  // "ahead" along the ego's heading (highway bends)
    cx = D.view.cx !== null ? D.view.cx : ego[0] + D.view.ahead * Math.cos(h);
    cy = D.view.cy !== null ? D.view.cy : ego[1] + D.view.ahead * Math.sin(h);
    drawRoad(); drawLights(k); drawAgents(k); drawLabels(k, [drawScale()]);
    var text = lines(k);
    out.textContent = text[0];
    box.textContent = text.slice(1).join("\n");
    root.setAttribute("data-frame", k);
    root.setAttribute("data-t", T[k].toFixed(2));
    root.setAttribute("data-draws", ++draws);
  }
  function stop() { clearInterval(timer); timer = null; play.textContent = "\u25b6 play"; }
  play.onclick = function () {
    if (timer !== null) return stop();
    if (+slider.value >= N - 1) draw(slider.value = 0);
    play.textContent = "\u275a\u275a pause";
    timer = setInterval(function () {
      if (+slider.value >= N - 1) return stop();
      draw(++slider.value);
    }, Math.max(20, N > 1 ? (T[N - 1] - T[0]) / (N - 1) * 1000 : 200));
  };
  root.querySelector(".first").onclick = function () { stop(); draw(slider.value = D.first); };
  slider.oninput = function () { draw(+slider.value); };
  function fromHash() {
    var m = /(?:^|[#&])t=([0-9.]+)/.exec(location.hash), best = 0;
    if (!m) return false;
    for (var i = 1; i < N; i++) if (Math.abs(T[i] - m[1]) < Math.abs(T[best] - m[1])) best = i;
    slider.value = best;
    slider.dispatchEvent(new Event("input"));
    return true;
  }
  addEventListener("hashchange", fromHash);
  if (!fromHash()) draw(D.first);
}
"""


def _compact(js: str) -> str:
    """``js`` without indentation, blank lines and ``  // comments`` (none sits in a string)."""
    lines = (re.sub(r"\s+// .*$", "", line).strip() for line in js.splitlines())
    return "\n".join(line for line in lines if line)


_SHIPPED_JS = _compact(PLAYER_JS)


def player_file() -> tuple[str, str]:
    """``(name, text)`` of the player script the cards of a report share: its name carries
    a hash of its text, so a card never runs another version's player."""
    import hashlib

    return f"replay-{hashlib.sha256(_SHIPPED_JS.encode()).hexdigest()[:8]}.js", _SHIPPED_JS


def _json_for_script(data: Mapping[str, Any]) -> str:
    # "<" escaped: no "</script>" (nor "<!--") inside a name can end the data block early
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def _decision_frames(data: Mapping[str, Any]) -> list[int]:
    """The frames at which the ego's decision changes: ticks on the slider."""
    made = data.get("decisions")
    if not made:
        return []
    times: list[int] = []  # centiseconds of every frame, from the first value + differences
    acc = 0
    for item in data["t"]:
        d, count = item if isinstance(item, list) else (item, 1)
        for _ in range(count):
            acc += d
            times.append(acc)
    import bisect

    return sorted({bisect.bisect_left(times, cs) for cs, _ in made["at"]} - {len(times)})


def player_html(data: Mapping[str, Any], element_id: str = "replay", player: str | None = None) -> str:
    """The player section of a card page for recording ``data``: canvas, slider, play/pause,
    the frame's metric values, the data itself and the player script — inline, or with
    ``player`` the address of the shared file of :func:`player_file` (~10 KB less per card;
    still no network)."""
    eid = html.escape(element_id, quote=True)
    n = sum(item[1] if isinstance(item, list) else 1 for item in data["t"])  # runs: [item, count]
    first = int(data["first"])
    size = data["view"]["size"]
    what = {"violation": "first violation", "contact": "first contact"}.get(data.get("first_kind"), "moment shown")
    critical = data.get("critical")
    of = f" of the {html.escape(str(data['case']))} case" if data.get("case") else ""
    legend = (f"Starts at the {what}{of} (t = {data['first_t']:.2f} s). Arrows: where each agent is "
              f"{data.get('arrow_s', 1.0):g} s later at its current speed; "
              + (f"ringed: {html.escape(critical)}, the critical agent; " if critical else "")
              + "red outline: crashed. "
              + ("Ticks on the slider: the first violation and where the ego's decision changes. "
                 if data.get("decisions") else "")
              + "Drag the slider or use ← → on it; "
              f"<code>#t=…</code> on the page's address opens the replay at that time.")
    return "\n".join([
        f"<style>{PLAYER_CSS}</style>",
        f"<section class='replay' id='{eid}' data-frame='{first}' data-draws='0'>",
        f"<canvas width='{int(size[0])}' height='{int(size[1])}' "
        f"aria-label='bird&#x27;s-eye replay of the run'></canvas>",
        "<div class='controls'>",
        "<button type='button' class='play'>&#9654; play</button>",
        f"<input type='range' min='0' max='{n - 1}' step='1' value='{first}' list='{eid}-marks' "
        f"aria-label='time'>",
        f"<datalist id='{eid}-marks'>"
        + "".join(f"<option value='{k}'></option>" for k in sorted({first, *_decision_frames(data)}))
        + "</datalist>",
        f"<output>t = {data['first_t']:.2f} s</output>",
        f"<button type='button' class='first'>{html.escape(what)}</button>",
        "</div>",
        "<pre class='values'></pre>",
        f"<p class='meta'>{legend}</p>",
        f"<script type='application/json' id='{eid}-data'>{_json_for_script(data)}</script>",
        (f"<script src='{html.escape(player, quote=True)}'></script>" if player is not None
         else f"<script>{_SHIPPED_JS}</script>"),
        f"<script>avsReplay({json.dumps(element_id)});</script>",
        "</section>",
    ])
