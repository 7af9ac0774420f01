/* bandada's live map: the page. The server sends frames (what changed, model.py) over a
   WebSocket; this draws them with Leaflet and sends the operator's requests back, each
   checked by the server as `gcs` checks it, confirmed here, and answered vehicle by
   vehicle. Text from the vehicles is always set as text, never as HTML. */
"use strict";

(function () {
  const $ = (id) => document.getElementById(id);
  const params = new URLSearchParams(location.search);
  const TOKEN = params.get("token") || "";
  const FLEET_COLORS = ["#9e9e9e", "#1e88e5", "#43a047", "#fb8c00", "#8e24aa", "#00acc1",
    "#fdd835", "#6d4c41", "#e91e63", "#3949ab"];
  const VEHICLE_COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
    "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
  const fleetColor = (f) => FLEET_COLORS[(f || 0) % FLEET_COLORS.length];

  const stats = { frames: 0, frameMs: [], applyMs: [], lagMs: [], bytes: 0, epoch: 0 };
  window.mapStats = stats;
  const keep = (arr, x, n) => { arr.push(x); if (arr.length > n) arr.shift(); };

  const state = {
    config: null, ws: null, rid: 0, pending: new Map(), epoch: 0, now: 0, trailS: 300,
    vehicles: new Map(), order: [], sel: new Set(), selAll: false, selFleet: null,
    selMode: "uav", focused: null, fitted: false, missions: [], zones: [], base: null,
    draw: null, geometry: null, file: null, replay: null, seeking: false,
  };
  window.mapState = state;

  // ------------------------------------------------------------------ the map
  const map = L.map("map", { boxZoom: false, doubleClickZoom: false, zoomSnap: 0.25 })
    .setView([0, 0], 2);
  window.leafletMap = map;
  L.control.scale({ metric: true, imperial: false, position: "bottomright", maxWidth: 160 }).addTo(map);
  const layers = {
    grid: L.layerGroup().addTo(map), zones: L.layerGroup().addTo(map),
    missions: L.layerGroup().addTo(map), shares: L.layerGroup().addTo(map),
    homes: L.layerGroup().addTo(map), trails: L.layerGroup().addTo(map),
    errors: L.layerGroup().addTo(map), drawing: L.layerGroup().addTo(map),
  };
  const gridLabel = document.createElement("div");
  gridLabel.className = "gridlabel panel dim";
  document.body.appendChild(gridLabel);

  function niceStep(m) {
    const p = Math.pow(10, Math.floor(Math.log10(m)));
    for (const k of [1, 2, 5, 10]) if (k * p >= m) return k * p;
    return 10 * p;
  }

  function drawGrid() {  // a metric grid where there are no tiles
    layers.grid.clearLayers();
    if (state.config && state.config.tiles) { gridLabel.classList.add("hidden"); return; }
    const b = map.getBounds(), c = map.getCenter();
    const mPerPx = 40075016.686 * Math.cos(c.lat * Math.PI / 180) / Math.pow(2, map.getZoom() + 8);
    const step = niceStep(Math.max(1, mPerPx * 90));
    const dLat = step / 111320, dLon = step / (111320 * Math.max(0.01, Math.cos(c.lat * Math.PI / 180)));
    const style = { color: "#b8c2cc", weight: 1, interactive: false };
    let n = 0;
    for (let la = Math.floor(b.getSouth() / dLat) * dLat; la <= b.getNorth() && n < 200; la += dLat, n++)
      L.polyline([[la, b.getWest()], [la, b.getEast()]], style).addTo(layers.grid);
    for (let lo = Math.floor(b.getWest() / dLon) * dLon; lo <= b.getEast() && n < 400; lo += dLon, n++)
      L.polyline([[b.getSouth(), lo], [b.getNorth(), lo]], style).addTo(layers.grid);
    gridLabel.textContent = `grid ${step >= 1000 ? step / 1000 + " km" : step + " m"}`;
    gridLabel.classList.remove("hidden");
  }
  map.on("moveend zoomend", drawGrid);

  // ------------------------------------------------------------------ icons
  const SHAPES = {
    PLANE: '<path d="M0,-14 L2.5,-6 L14,1 L14,4 L2.5,1 L2,9 L6,12 L6,14 L0,12.5 L-6,14 L-6,12 L-2,9 L-2.5,1 L-14,4 L-14,1 L-2.5,-6 Z"/>',
    VTOL: '<path d="M0,-14 L2.5,-6 L14,1 L14,4 L2.5,1 L2,9 L6,12 L6,14 L0,12.5 L-6,14 L-6,12 L-2,9 L-2.5,1 L-14,4 L-14,1 L-2.5,-6 Z"/>' +
      '<circle cx="-9" cy="-4" r="3.2"/><circle cx="9" cy="-4" r="3.2"/><circle cx="-9" cy="8" r="3.2"/><circle cx="9" cy="8" r="3.2"/>',
    COPTER: '<path d="M-9,-9 L9,9 M9,-9 L-9,9" stroke-width="3"/><circle cx="-9" cy="-9" r="4.5"/><circle cx="9" cy="-9" r="4.5"/>' +
      '<circle cx="-9" cy="9" r="4.5"/><circle cx="9" cy="9" r="4.5"/><path d="M0,-15 L4,-8 L-4,-8 Z"/>',
    ROVER: '<rect x="-7" y="-11" width="14" height="22" rx="3"/><path d="M0,-16 L5,-10 L-5,-10 Z"/>',
    BOAT: '<path d="M0,-15 C7,-6 7,6 6,13 L-6,13 C-7,6 -7,-6 0,-15 Z"/>',
    OTHER: '<path d="M0,-14 L10,12 L0,7 L-10,12 Z"/>',
  };
  SHAPES.MANNED = SHAPES.PLANE;

  function iconHtml(v) {
    const shape = SHAPES[v.data.type] || SHAPES.OTHER;
    const color = fleetColor(v.data.fleet);
    return `<div class="veh"><svg viewBox="-20 -20 40 40">` +
      `<circle class="halo" r="19"/><circle class="ring" r="16"/>` +
      `<g class="body" fill="${color}" stroke="#1a1a1a" stroke-width="1.2">${shape}` +
      `<circle r="5" stroke="none"/></g></svg><div class="label"></div></div>`;
  }

  function makeMarker(v) {
    const icon = L.divIcon({ html: iconHtml(v), className: "", iconSize: [40, 40], iconAnchor: [20, 20] });
    const m = L.marker([v.data.lat, v.data.lon], { icon, keyboard: false, riseOnHover: true });
    m.on("click", (e) => { L.DomEvent.stopPropagation(e); clickVehicle(v.id); });
    m.addTo(map);
    v.marker = m;
    v.iconKey = `${v.data.type}/${v.data.fleet}`;
    v.el = m.getElement();
    v.el.dataset.vehicle = v.id;
  }

  function styleMarker(v) {
    const d = v.data, link = v.link || {};
    if (!d.has_position || v.hidden) {
      if (v.marker) { v.marker.remove(); v.marker = null; }
      return;
    }
    const key = `${d.type}/${d.fleet}`;
    if (v.marker && v.iconKey !== key) { v.marker.remove(); v.marker = null; }
    if (!v.marker) makeMarker(v);
    v.marker.setLatLng([d.lat, d.lon]);
    const el = v.el;
    if (!el) return;
    const svg = el.querySelector("svg");
    const rot = `rotate(${d.heading_deg || 0}deg)`;
    if (svg.style.transform !== rot) svg.style.transform = rot;
    const cls = ["veh", d.worst || "", state.sel.has(v.id) ? "sel" : "", link.lost ? "lost" : ""]
      .filter(Boolean).join(" ");
    const box = el.firstChild;
    if (box.className !== cls) box.className = cls;
    const label = el.querySelector(".label");
    const text = String(v.id);
    if (label.textContent !== text) label.textContent = text;
  }

  // ------------------------------------------------------------------ vehicles
  function vehicleColor(id) {
    const i = state.order.indexOf(id);
    return VEHICLE_COLORS[(i < 0 ? 0 : i) % VEHICLE_COLORS.length];
  }

  function vehicle(id) {
    let v = state.vehicles.get(id);
    if (!v) {
      v = { id, data: { id, type: "OTHER" }, link: null, marker: null, el: null, trail: [],
        trailLine: null, trailOn: true, hidden: false, errCircle: null, home: null, row: null };
      state.vehicles.set(id, v);
      state.order = [...state.vehicles.keys()].sort((a, b) => a - b);
    }
    return v;
  }

  function updateVehicle(d) {
    const v = vehicle(d.id);
    v.data = d;
    if (d.t && state.config && state.config.mode === "live") {
      keep(stats.lagMs, Date.now() - d.t * 1000, 20000);
    }
    styleMarker(v);
    // a radio gateway's prediction: the truth is within position_error_m
    const err = d.position_error_m || 0;
    if (err > 0 && d.has_position && !v.hidden) {
      if (!v.errCircle) v.errCircle = L.circle([d.lat, d.lon], { radius: err, color: "#555", weight: 1, dashArray: "4 3", fill: false, interactive: false }).addTo(layers.errors);
      v.errCircle.setLatLng([d.lat, d.lon]); v.errCircle.setRadius(err);
    } else if (v.errCircle) { v.errCircle.remove(); v.errCircle = null; }
    const h = d.home;
    if (h && !v.home) {
      v.home = L.marker([h[0], h[1]], { icon: L.divIcon({ html: "⌂", className: "mark", iconSize: [16, 16] }), interactive: false }).addTo(layers.homes);
      v.home.getElement().style.color = vehicleColor(v.id);
    } else if (h && v.home) v.home.setLatLng([h[0], h[1]]);
  }

  function addTrail(id, pts) {
    const v = vehicle(id);
    for (const p of pts) v.trail.push([p[1], p[2], p[0]]);
    trimTrail(v);
  }

  function trimTrail(v) {
    const cut = state.now - state.trailS;
    let i = 0;
    while (i < v.trail.length && v.trail[i][2] < cut) i++;
    if (i) v.trail.splice(0, i);
    const show = v.trailOn && !v.hidden && v.trail.length > 1;
    if (show) {
      const pts = v.trail.map((p) => [p[0], p[1]]);
      if (v.data.has_position) pts.push([v.data.lat, v.data.lon]);
      if (!v.trailLine) v.trailLine = L.polyline(pts, { color: vehicleColor(v.id), weight: 2, opacity: 0.8, interactive: false }).addTo(layers.trails);
      else v.trailLine.setLatLngs(pts);
    } else if (v.trailLine) { v.trailLine.remove(); v.trailLine = null; }
  }

  // ------------------------------------------------------------------ the vehicle list and the PFD
  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }

  const EYE = '<path d="M1,8 C4,3 12,3 15,8 C12,13 4,13 1,8 Z" fill="none" stroke="#333" stroke-width="1.4"/><circle cx="8" cy="8" r="2.4" fill="#333"/>';
  const FOCUS = '<circle cx="8" cy="8" r="5" fill="none" stroke="#333" stroke-width="1.4"/><path d="M8,0 V4 M8,12 V16 M0,8 H4 M12,8 H16" stroke="#333" stroke-width="1.4"/>';
  const TRAIL = '<path d="M1,13 C4,2 7,14 10,6 S14,3 15,3" fill="none" stroke="#333" stroke-width="1.6"/>';
  function svgButton(cls, inner) {
    const b = el("button", cls);
    b.innerHTML = `<svg viewBox="0 0 16 16" width="14" height="14">${inner}</svg>`;  // our own markup
    return b;
  }

  function renderList() {
    const box = $("vrows");
    if (!state.order.length) return;
    if (box.classList.contains("dim")) { box.classList.remove("dim"); box.textContent = ""; }
    for (const id of state.order) {
      const v = state.vehicles.get(id);
      if (!v.row) {
        const row = el("div", "vrow");
        row.dataset.id = id;
        const name = el("span", "name"), pps = el("span", "pps");
        const eye = svgButton("eye", EYE), focus = svgButton("focus", FOCUS), trail = svgButton("trail", TRAIL);
        eye.title = "show or hide on the map"; focus.title = "centre the map on it"; trail.title = "its trajectory";
        row.append(name, pps, eye, focus, trail);
        row.addEventListener("click", () => { state.focused = id; renderPfd(); });
        eye.addEventListener("click", (e) => { e.stopPropagation(); v.hidden = !v.hidden; styleMarker(v); trimTrail(v); renderList(); });
        focus.addEventListener("click", (e) => { e.stopPropagation(); if (v.data.has_position) map.setView([v.data.lat, v.data.lon], Math.max(map.getZoom(), 16)); state.focused = id; renderPfd(); });
        trail.addEventListener("click", (e) => { e.stopPropagation(); v.trailOn = !v.trailOn; trimTrail(v); renderList(); });
        v.row = { row, name, pps, eye, trail };
        const after = state.order.slice(state.order.indexOf(id) + 1).map((x) => state.vehicles.get(x).row).find(Boolean);
        box.insertBefore(row, after ? after.row : null);
      }
      const d = v.data, link = v.link || {};
      const who = `${id} ${d.user_id || ""} ${d.type !== "OTHER" ? d.type : ""}`.trim();
      if (v.row.name.textContent !== who) v.row.name.textContent = who;
      const pps = link.lost ? "lost" : `${(link.pps || 0).toFixed(1)}/s`;
      if (v.row.pps.textContent !== pps) v.row.pps.textContent = pps;
      v.row.row.style.borderColor = fleetColor(d.fleet);
      v.row.row.classList.toggle("sel", state.sel.has(id));
      v.row.row.classList.toggle("lost", !!link.lost);
      v.row.eye.classList.toggle("off", v.hidden);
      v.row.trail.classList.toggle("off", !v.trailOn);
    }
  }

  // the flight display: built once per vehicle shown, its values updated in place (a
  // button pressed while a frame arrives must not be replaced under the pointer)
  const SVG = "http://www.w3.org/2000/svg";
  function svgEl(tag, attrs) {
    const e = document.createElementNS(SVG, tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    return e;
  }

  function buildPfd(v) {
    const box = $("pfd");
    box.textContent = "";
    const p = {};
    const head = el("div", "title");
    const close = el("button", "", "×"); close.style.float = "right";
    close.addEventListener("click", () => { state.focused = null; renderPfd(); });
    p.title = el("span");
    head.append(close, p.title);
    const grid = el("div", "grid");
    const left = el("div"), mid = el("div"), right = el("div");
    p.gs = el("div", "big"); p.as = el("div", "big"); p.base = el("div");
    left.append(el("div", "dim", "ground speed"), p.gs, el("div", "dim", "airspeed"), p.as, p.base);
    const svg = svgEl("svg", { viewBox: "-50 -50 100 100", width: 110, height: 110 });
    const clip = svgEl("clipPath", { id: "pfdclip" });
    clip.append(svgEl("circle", { r: 48 }));
    p.horizon = svgEl("g", {});
    p.horizon.append(svgEl("rect", { x: -150, y: -150, width: 300, height: 150, fill: "#5aa0e6" }),
      svgEl("rect", { x: -150, y: 0, width: 300, height: 150, fill: "#a0703c" }));
    const wrap = svgEl("g", { "clip-path": "url(#pfdclip)" });
    wrap.append(p.horizon);
    svg.append(clip, wrap, svgEl("path", { d: "M-30,0 L-10,0 L0,8 L10,0 L30,0", stroke: "#ff0", "stroke-width": 3, fill: "none" }));
    p.att = el("div");
    mid.append(svg, p.att);
    p.alt = el("div", "big"); p.msl = el("div", "dim"); p.battery = el("div"); p.gps = el("div");
    right.append(el("div", "dim", "altitude"), p.alt, p.msl, p.battery, p.gps);
    grid.append(left, mid, right);
    p.sensors = el("div", "sensors"); p.state = el("div"); p.alerts = el("div"); p.mismatch = el("div", "bad");
    p.trail = el("button");
    p.trail.addEventListener("click", () => { v.trailOn = !v.trailOn; trimTrail(v); renderPfd(); renderList(); });
    // a LOST vehicle accounted for: off the ground station's list (as `gcs dismiss ID`)
    p.dismiss = el("button", "", "Dismiss (accounted for)");
    p.dismiss.addEventListener("click", async () => {
      if (!confirm(`vehicle ${v.id} is accounted for: take it off the map?`)) return;
      const r = await send("dismiss", { id: v.id });
      if (!r.ok) showError(r.error);
    });
    box.append(head, grid, p.sensors, p.state, p.alerts, p.trail, p.dismiss, p.mismatch);
    return p;
  }

  function setText(e, text, cls) {
    if (e.textContent !== text) e.textContent = text;
    if (cls !== undefined && e.className !== cls) e.className = cls;
  }

  function renderPfd() {
    const box = $("pfd");
    const v = state.vehicles.get(state.focused);
    if (!v) { box.classList.add("hidden"); state.pfd = null; return; }
    if (!state.pfd || state.pfd.id !== v.id) state.pfd = { id: v.id, p: buildPfd(v) };
    const p = state.pfd.p, d = v.data, link = v.link || {};
    const f = (x, unit, nd = 1) => (x === undefined || x === null ? "-" : `${Number(x).toFixed(nd)}${unit}`);
    box.classList.remove("hidden");
    setText(p.title, `vehicle ${d.id} ${d.model || ""} ${d.user_id ? "(" + d.user_id + ")" : ""}`);
    setText(p.gs, f(d.groundspeed_m_s, " m/s"));
    setText(p.as, f(d.airspeed_m_s, " m/s"));
    setText(p.base, `base ${d.base ? d.base[0].toFixed(5) + ", " + d.base[1].toFixed(5) : "not set"}`);
    p.horizon.setAttribute("transform", `rotate(${-(d.roll_deg || 0)}) translate(0 ${(d.pitch_deg || 0) * 1.5})`);
    setText(p.att, `hdg ${f(d.heading_deg, "°", 0)} roll ${f(d.roll_deg, "°", 0)} pitch ${f(d.pitch_deg, "°", 0)}`);
    setText(p.alt, f(d.alt_rel_m, " m"));
    setText(p.msl, `${f(d.alt_msl_m, " m")} MSL, climb ${f(d.climb_m_s, " m/s")}`);
    setText(p.battery, `battery ${d.battery_pct >= 0 ? d.battery_pct + " %" : "?"} ${f(d.battery_v, " V", 2)}`,
      d.battery_pct >= 0 && d.battery_pct < 25 ? "bad" : "");
    setText(p.gps, `GPS ${d.gps_fix || "-"} ${d.gps_sats !== undefined ? d.gps_sats + " sats" : ""}`);
    const sensors = Object.entries(d.sensors || {});
    const key = sensors.map((x) => x.join(" ")).join(",");
    if (p.sensorsKey !== key) {
      p.sensorsKey = key;
      p.sensors.textContent = "";
      for (const [name, st] of sensors) p.sensors.append(el("span", st === "ok" ? "" : "bad", `${name} ${st}`));
    }
    setText(p.state, `${d.fsm || "-"} / ${d.mission_state || "-"} ${d.progress_pct ?? ""}% · ${d.mode || "-"} ${d.armed ? "ARMED" : "disarmed"} · fleet ${d.fleet ?? "-"} · mission ${d.mission_id || "-"} · link ${link.lost ? "LOST" : f(link.age_s, " s")} ${f(link.pps, "/s")}`);
    setText(p.alerts, (d.alerts && d.alerts.length) ? `alerts: ${d.alerts.join(", ")}` : "no active alert", d.worst ? "bad" : "dim");
    setText(p.trail, v.trailOn ? "Hide trajectory" : "Show trajectory");
    p.dismiss.classList.toggle("hidden", !link.lost);
    const pr = link.predicted, last = link.last;
    if (link.lost && last) {
      const where = pr ? `; predicted ${pr.lat.toFixed(5)}, ${pr.lon.toFixed(5)} ${pr.alt_rel_m.toFixed(0)} m ±${pr.error_m.toFixed(0)} m (${pr.phase})` : "";
      setText(p.mismatch, `LOST ${last.age_s.toFixed(0)} s: last ${last.lat.toFixed(5)}, ${last.lon.toFixed(5)} ${last.alt_rel_m.toFixed(0)} m${where}`);
      return;
    }
    setText(p.mismatch, d.autopilot_mismatch ? `autopilot: ${d.autopilot_mismatch}` : "");
  }

  // ------------------------------------------------------------------ selection
  function selectionReq() {
    if (state.selAll) return { all: true };
    if (state.selFleet !== null) return { fleet: state.selFleet };
    return { ids: [...state.sel].sort((a, b) => a - b) };
  }

  function setSelection(ids, how) {
    state.sel = new Set(ids);
    state.selAll = how === "all";
    state.selFleet = typeof how === "number" ? how : null;
    let text;
    if (state.selAll) text = `all vehicles alive (${state.sel.size} shown)`;
    else if (state.selFleet !== null) text = `fleet ${state.selFleet}: ${[...state.sel].join(", ")}`;
    else text = state.sel.size ? `vehicles ${[...state.sel].sort((a, b) => a - b).join(", ")}` : "nothing selected (shift-drag: a box)";
    $("sel-text").textContent = text;
    for (const v of state.vehicles.values()) styleMarker(v);
    renderList();
    renderIdList();
  }

  function clickVehicle(id) {
    if (state.draw) return;
    state.focused = id;
    renderPfd();
    if (state.selMode === "fleet") {
      const f = state.vehicles.get(id).data.fleet || 0;
      const ids = [...state.vehicles.values()].filter((v) => (v.data.fleet || 0) === f).map((v) => v.id);
      setSelection(ids, f > 0 ? f : undefined);
      return;
    }
    const ids = new Set(state.selAll || state.selFleet !== null ? [] : state.sel);
    if (ids.has(id)) ids.delete(id); else ids.add(id);
    setSelection([...ids]);
  }

  function setMode(mode) {
    state.selMode = mode;
    $("sel-uav").classList.toggle("on", mode === "uav");
    $("sel-fleet").classList.toggle("on", mode === "fleet");
  }
  $("sel-uav").onclick = () => setMode("uav");
  $("sel-fleet").onclick = () => setMode("fleet");
  $("sel-all").onclick = () => setSelection([...state.vehicles.values()].filter((v) => !(v.link || {}).lost).map((v) => v.id), "all");
  $("sel-none").onclick = () => setSelection([]);
  $("sel-id").onclick = () => {
    const box = $("idlist");
    box.classList.toggle("hidden");
    if (!box.classList.contains("hidden")) renderIdList();
  };
  function renderIdList() {
    const box = $("idlist");
    if (box.classList.contains("hidden")) return;
    const key = state.order.join(",") + "|" + [...state.sel].join(",");
    if (box.dataset.key === key) return;
    box.dataset.key = key;
    box.textContent = "";
    for (const id of state.order) {
      const d = state.vehicles.get(id).data;
      const label = el("label", "idpick");
      const cb = el("input");
      cb.type = "checkbox"; cb.checked = state.sel.has(id); cb.dataset.id = id;
      cb.onchange = () => {
        const ids = [...box.querySelectorAll("input:checked")].map((c) => Number(c.dataset.id));
        setSelection(ids);
      };
      label.append(cb, document.createTextNode(` ${id} ${d.user_id || ""}`));
      box.append(label);
    }
  }
  $("btn-fit").onclick = () => fitAll();

  function fitAll() {
    const pts = [...state.vehicles.values()].filter((v) => v.data.has_position).map((v) => [v.data.lat, v.data.lon]);
    if (pts.length) map.fitBounds(L.latLngBounds(pts).pad(0.5), { maxZoom: 18 });
  }

  // shift-drag: a box selects the vehicles inside it
  let box = null;
  map.getContainer().addEventListener("mousedown", (e) => {
    if (!e.shiftKey || state.draw) return;
    e.preventDefault(); e.stopPropagation();
    map.dragging.disable();
    const start = map.mouseEventToLatLng(e);
    box = { start, rect: L.rectangle([start, start], { color: "#2a6fdb", weight: 1, dashArray: "4 3" }).addTo(map) };
  }, true);
  map.getContainer().addEventListener("mousemove", (e) => {
    if (box) box.rect.setBounds(L.latLngBounds(box.start, map.mouseEventToLatLng(e)));
  });
  window.addEventListener("mouseup", (e) => {
    if (!box) return;
    const bounds = L.latLngBounds(box.start, map.mouseEventToLatLng(e));
    box.rect.remove(); box = null;
    map.dragging.enable();
    const ids = [...state.vehicles.values()].filter((v) => v.data.has_position && !v.hidden && bounds.contains([v.data.lat, v.data.lon])).map((v) => v.id);
    setSelection(ids);
  });

  // ------------------------------------------------------------------ requests
  function send(op, req) {
    return new Promise((resolve) => {
      if (!state.ws || state.ws.readyState !== 1) { resolve({ ok: false, error: "not connected" }); return; }
      const rid = ++state.rid;
      state.pending.set(rid, resolve);
      state.ws.send(JSON.stringify({ op, rid, token: TOKEN, req }));
    });
  }

  let errorTimer = null;
  $("error").onclick = () => $("error").classList.add("hidden");
  function showError(text) {
    const e = $("error");
    e.textContent = text;
    e.classList.remove("hidden");
    clearTimeout(errorTimer);
    errorTimer = setTimeout(() => e.classList.add("hidden"), 12000);
  }

  function confirmBox(question) {
    return new Promise((resolve) => {
      $("modal-question").textContent = question;
      $("modal").classList.remove("hidden");
      const done = (ok) => { $("modal").classList.add("hidden"); $("modal-ok").onclick = $("modal-cancel").onclick = null; resolve(ok); };
      $("modal-ok").onclick = () => done(true);
      $("modal-cancel").onclick = () => done(false);
    });
  }

  // check (the server's validators), confirm (naming the vehicles), send
  async function request(req) {
    $("error").classList.add("hidden");
    const checked = await send("check", req);
    if (!checked.ok) { showError(checked.error); return false; }
    if (!(await confirmBox(checked.question))) return false;
    const sent = await send("send", { ...req, ...(checked.fixed || {}) });  // as confirmed (its ids)
    if (!sent.ok) { showError(sent.error); return false; }
    return true;
  }
  window.mapRequest = request;

  function command(kind, extra = {}, select = null) {
    return request({ type: "command", kind, select: select || selectionReq(), ...extra });
  }

  // ------------------------------------------------------------------ drawing
  function startDraw(kind, text, onDone) {
    cancelDraw();
    state.draw = { kind, pts: [], onDone };
    $("draw-text").textContent = text;
    $("draw-finish").classList.toggle("hidden", kind === "circle" || kind === "point");
    $("drawbar").classList.remove("hidden");
    map.getContainer().style.cursor = "crosshair";
  }

  function cancelDraw() {
    state.draw = null;
    layers.drawing.clearLayers();
    $("drawbar").classList.add("hidden");
    map.getContainer().style.cursor = "";
  }

  function redrawSketch(cursor) {
    const d = state.draw;
    layers.drawing.clearLayers();
    if (!d) return;
    const pts = cursor ? [...d.pts, cursor] : d.pts;
    const style = { color: "#2a6fdb", weight: 2, dashArray: "5 4", interactive: false };
    if (d.kind === "circle" && d.pts.length === 1 && cursor)
      L.circle(d.pts[0], { radius: map.distance(d.pts[0], cursor), ...style }).addTo(layers.drawing);
    else if (d.kind === "polygon" && pts.length > 2) L.polygon(pts, style).addTo(layers.drawing);
    else if (pts.length > 1 && d.kind !== "points") L.polyline(pts, style).addTo(layers.drawing);
    for (const p of d.pts) L.circleMarker(p, { radius: 3, color: "#2a6fdb", interactive: false }).addTo(layers.drawing);
  }

  function finishDraw() {
    const d = state.draw;
    if (!d) return;
    const ll = d.pts.map((p) => [round7(p.lat), round7(p.lng)]);
    let geometry = null;
    if (d.kind === "polygon" && ll.length >= 3) geometry = { polygon: ll };
    else if (d.kind === "line" && ll.length >= 2) geometry = { line: ll };
    else if (d.kind === "points" && ll.length >= 1) geometry = { points: ll };
    else if (d.kind === "circle" && ll.length === 2)
      geometry = { circle: [ll[0][0], ll[0][1], Math.round(map.distance(d.pts[0], d.pts[1]) * 10) / 10] };
    else if (d.kind === "point" && ll.length === 1) geometry = { point: ll[0] };
    const done = d.onDone;
    cancelDraw();
    if (geometry) done(geometry);
  }
  const round7 = (x) => Math.round(x * 1e7) / 1e7;

  map.on("click", (e) => {
    const d = state.draw;
    if (!d) return;
    d.pts.push(e.latlng);
    if ((d.kind === "circle" && d.pts.length === 2) || (d.kind === "point" && d.pts.length === 1)) { finishDraw(); return; }
    redrawSketch();
  });
  map.on("dblclick", (e) => { if (state.draw) { L.DomEvent.stop(e); finishDraw(); } });
  map.on("mousemove", (e) => { if (state.draw && state.draw.pts.length) redrawSketch(e.latlng); });
  $("draw-finish").onclick = finishDraw;
  $("draw-cancel").onclick = cancelDraw;
  document.addEventListener("keydown", (e) => { if (e.key === "Escape") cancelDraw(); });

  // ------------------------------------------------------------------ the command menu
  $("btn-menu").onclick = () => $("menu").classList.toggle("hidden");
  for (const b of document.querySelectorAll("#menu .tabs button")) {
    b.onclick = () => {
      for (const o of document.querySelectorAll("#menu .tabs button")) o.classList.toggle("on", o === b);
      for (const t of document.querySelectorAll("#menu .tab")) t.classList.toggle("hidden", t.id !== `tab-${b.dataset.tab}`);
    };
  }

  // fast actions
  $("btn-emergency").onclick = () => startDraw("point", "Emergency landing: click where the landing route ends",
    (g) => command("emergency-land", { point: g.point }, state.sel.size || state.selAll ? null : { all: true }));
  $("btn-abort").onclick = () => command("abort-landing", {}, state.sel.size || state.selAll ? null : { all: true });
  $("btn-parachute").onclick = () => command("parachute", {}, { all: true });

  // base
  $("btn-set-base").onclick = () => startDraw("point", "Set base: click where it is", (g) =>
    request({ type: "command", kind: "set-base", point: [...g.point, $("base-alt").value || 0], select: { all: true } }));

  // actions
  $("btn-arm").onclick = () => command("arm");
  $("btn-disarm").onclick = () => command("disarm");
  $("btn-takeoff").onclick = () => command("takeoff", { value: $("a-alt").value });
  $("btn-rtl").onclick = () => command("rtl");
  $("btn-land").onclick = () => command("land");
  $("btn-activate").onclick = () => command("activate");
  $("btn-join").onclick = () => command("join-mission", { mission_id: $("a-mission").value });
  $("btn-swap").onclick = () => command("swap-mission", { mission_id: $("a-mission").value, other_mission_id: $("a-other").value });
  $("btn-calibrate").onclick = () => command("calibrate", { text: $("a-what").value });
  $("btn-cancel-mission").onclick = () => command("cancel-mission", { mission_id: $("a-mission").value });

  // zones
  const zoneReq = (g) => request({ type: "zone", ...g, floor: $("z-floor").value, ceiling: $("z-ceiling").value,
    name: $("z-name").value, operating_area: $("z-area").checked });
  $("z-draw-circle").onclick = () => startDraw("circle", "Zone: click the centre, then the edge", zoneReq);
  $("z-draw-polygon").onclick = () => startDraw("polygon", "Zone: click the corners; double-click or Finish closes it", zoneReq);

  // missions
  function setGeometry(g, text) {
    state.geometry = g; state.file = null;
    $("m-geometry").textContent = text;
  }
  const drawn = (kind) => (g) => setGeometry(g, `drawn: ${kind}`);
  $("m-draw-polygon").onclick = () => startDraw("polygon", "Mission: click the corners; double-click or Finish", drawn("polygon"));
  $("m-draw-circle").onclick = () => startDraw("circle", "Mission: click the centre, then the edge", drawn("circle"));
  $("m-draw-line").onclick = () => startDraw("line", "Mission route: click the points; double-click or Finish", drawn("line"));
  $("m-draw-point").onclick = () => startDraw("point", "Mission: click the point", drawn("point"));
  $("m-file").onchange = (e) => {
    const f = e.target.files[0];
    if (!f) return;
    const reader = new FileReader();
    reader.onload = () => {
      const data = reader.result.split(",", 2)[1] || "";
      state.geometry = null;
      state.file = { name: f.name, data };
      $("m-geometry").textContent = `file: ${f.name}`;
    };
    reader.readAsDataURL(f);
  };
  $("btn-mission").onclick = () => {
    if (!state.geometry && !state.file) { showError("draw the mission's geometry or load a file first"); return; }
    const count = $("m-count").value.trim();
    const req = { type: "mission", mission_type: $("m-type").value, alt: $("m-alt").value, speed: $("m-speed").value,
      name: $("m-name").value, ...(state.file ? { file: state.file } : state.geometry) };
    if (count) { req.count = count; if (state.selFleet !== null) req.select = { fleet: state.selFleet }; }
    else req.select = selectionReq();
    request(req);
  };

  // ------------------------------------------------------------------ overlays
  function drawGeometry(g, style, layer) {
    const pts = g.points;
    if (g.kind === "polygon") return L.polygon(g.holes ? [pts, ...g.holes] : pts, style).addTo(layer);
    if (g.kind === "circle") return L.circle(pts[0], { radius: g.radius_m, ...style }).addTo(layer);
    if (g.kind === "polyline") return L.polyline(pts, style).addTo(layer);
    const group = L.layerGroup(pts.map((p) => L.circleMarker(p, { radius: 6, ...style }))).addTo(layer);
    return group;
  }

  function renderZones(zones) {
    state.zones = zones;
    layers.zones.clearLayers();
    const list = $("zone-list");
    list.textContent = "";
    for (const z of zones) {
      const style = z.operating_area
        ? { color: "#2e7d32", weight: 2, dashArray: "8 5", fill: false }
        : { color: "#c62828", weight: 2, fillColor: "#e53935", fillOpacity: 0.3 };
      const shape = drawGeometry(z.geometry, style, layers.zones);
      shape.bindTooltip(el("span", "", `${z.operating_area ? "operating area" : "no-fly zone"} ${z.id} ${z.name || ""}`));
      const row = el("div", "row", `${z.operating_area ? "area" : "zone"} ${z.id} ${z.name || ""} `);
      const rm = el("button", "", "withdraw");
      rm.onclick = () => request({ type: "zone-remove", zone_id: z.id });
      row.append(rm);
      list.append(row);
    }
  }

  function renderMissions(missions) {
    state.missions = missions;
    layers.missions.clearLayers();
    layers.shares.clearLayers();
    for (const m of missions) {
      const shape = drawGeometry(m.geometry, { color: "#333", weight: 1.5, dashArray: "6 4", fillColor: "#888", fillOpacity: 0.08 }, layers.missions);
      shape.bindTooltip(el("span", "", `mission ${m.id} (${m.type}) ${m.name || ""}: ${m.selection}; flown by ${m.flying.join(", ") || "none"}; shares ${m.plan}`));
      for (const [vid, pts] of Object.entries(m.shares)) {
        const id = Number(vid);
        const lost = !m.flying.includes(id);
        L.polyline(pts, { color: vehicleColor(id), weight: 2, opacity: lost ? 0.35 : 0.9, dashArray: lost ? "2 6" : "6 3", interactive: false })
          .addTo(layers.shares);
      }
    }
  }

  function renderAlerts(alerts) {
    const box = $("alerts-list");
    if (box.classList.contains("dim")) { box.classList.remove("dim"); box.textContent = ""; }
    for (const a of alerts) {
      const t = new Date(a.time_unix_s * 1000).toISOString().slice(11, 19);
      box.prepend(el("div", `a ${a.severity}`, `${t} ${a.vehicle} ${a.severity} ${a.text}`));
    }
    while (box.children.length > 60) box.lastChild.remove();
  }

  function renderVote(v) {
    const box = $("vote-body");
    box.textContent = "";
    if (!v) { box.className = "dim"; box.textContent = "no vote heard"; return; }
    box.className = "";
    box.append(el("div", "", `mission ${v.mission_id}: ${v.decided ? "decided" : "voting"}${v.quantity ? `, ${v.quantity} wanted` : ""}`));
    const winners = new Set(v.winners);
    for (const [vid, score] of v.scores)
      box.append(el("div", winners.has(vid) ? "" : "dim", `${vid}: ${score.toFixed(4)} ${winners.has(vid) ? "goes" : "stays"}`));
    if (v.winners.length) box.append(el("div", "", `winners: ${v.winners.join(", ")}`));
  }

  function renderCommands(cmds) {
    const box = $("answers-list");
    box.textContent = "";
    box.className = cmds.length ? "" : "dim";
    if (!cmds.length) box.textContent = "no command sent";
    for (const c of cmds) {
      const e = el("div", `cmd ${c.state}`);
      e.dataset.cid = c.id;
      e.append(el("div", "q", c.question), el("div", c.state === "ok" ? "" : "bad", c.summary));
      for (const a of c.answers) {
        const r = el("div", `ans ${a.answer.replace(" ", "-")}`, `${a.id}: ${a.answer}${a.why ? " - " + a.why : ""}${a.notes && a.notes.length ? " (" + a.notes.join("; ") + ")" : ""}`);
        r.dataset.vehicle = a.id;
        e.append(r);
      }
      if (c.not_addressed && c.not_addressed.length) e.append(el("div", "dim", `not addressed: ${c.not_addressed.join(", ")}`));
      box.append(e);
    }
  }

  function renderSummary(s) {
    const box = $("summary");
    const key = JSON.stringify([s.count, s.by_state]);
    if (state.summaryKey !== key) { state.summaryKey = key; drawSummary(box, s); }
    baseInfo(s);
  }

  function drawSummary(box, s) {
    box.textContent = "";
    box.append(el("span", "", `${s.count} vehicle${s.count === 1 ? "" : "s"}`));
    for (const [name, ids] of Object.entries(s.by_state)) {
      if (!ids.length) continue;
      const b = el("span", `state ${name}`, `${name.toLowerCase().replace("_", " ")} ${ids.length}`);
      b.dataset.state = name;
      b.title = `select ${ids.join(", ")}`;
      b.onclick = () => setSelection(ids);
      box.append(b);
    }
  }

  function baseInfo(s) {
    state.base = s.base;
    $("base-info").textContent = s.base ? `base: ${s.base[0].toFixed(6)}, ${s.base[1].toFixed(6)}, ${s.base[2]} m${s.bases_disagree ? " (the vehicles disagree)" : ""}` : "base: not set";
    if (s.base) {
      if (!state.baseMarker) state.baseMarker = L.marker([s.base[0], s.base[1]], { icon: L.divIcon({ html: "★", className: "mark", iconSize: [18, 18] }), interactive: false }).addTo(layers.homes);
      else state.baseMarker.setLatLng([s.base[0], s.base[1]]);
      state.baseMarker.getElement().style.color = "#e0a800";
      if (!$("base-alt").value) $("base-alt").value = s.base[2];
    } else if (!$("base-alt").value) {
      const homes = [...state.vehicles.values()].map((v) => v.data.home).filter(Boolean);
      if (homes.length) $("base-alt").value = (homes.reduce((a, h) => a + h[2], 0) / homes.length).toFixed(1);
    }
  }

  // ------------------------------------------------------------------ replay
  function fmtT(s) { s = Math.max(0, s); return `${Math.floor(s / 60)}:${String(Math.floor(s % 60)).padStart(2, "0")}`; }
  function renderReplay(r) {
    state.replay = r;
    $("replaybar").classList.remove("hidden");
    $("r-play").textContent = r.playing ? "Pause" : "Play";
    if (!state.seeking) $("r-slider").value = Math.round(1000 * (r.t - r.t0) / Math.max(1e-9, r.t1 - r.t0));
    $("r-time").textContent = `${fmtT(r.t - r.t0)} / ${fmtT(r.t1 - r.t0)}`;
    const sel = $("r-speed");
    if (!sel.options.length) for (const s of r.speeds) sel.append(new Option(`${s}x`, s));
    if (Number(sel.value) !== r.speed) sel.value = r.speed;
  }
  $("r-play").onclick = () => send("replay", { action: state.replay && state.replay.playing ? "pause" : "play" });
  $("r-slider").oninput = () => { state.seeking = true; };
  $("r-slider").onchange = () => {
    const r = state.replay; state.seeking = false;
    if (r) send("replay", { action: "seek", t: r.t0 + (r.t1 - r.t0) * $("r-slider").value / 1000 });
  };
  $("r-speed").onchange = () => send("replay", { action: "speed", speed: Number($("r-speed").value) });

  // ------------------------------------------------------------------ frames
  function reset() {
    for (const v of state.vehicles.values()) if (v.marker) v.marker.remove();
    for (const k of ["zones", "missions", "shares", "homes", "trails", "errors"]) layers[k].clearLayers();
    state.vehicles = new Map(); state.order = []; state.baseMarker = null;
    state.pfd = null; state.summaryKey = null; $("idlist").dataset.key = "";
    $("vrows").textContent = "";
  }

  function apply(f) {
    const t0 = performance.now();
    if (f.full && f.epoch !== state.epoch) { if (state.epoch) reset(); state.epoch = f.epoch; stats.epoch = f.epoch; }
    state.now = f.now; state.trailS = f.trail_s;
    for (const d of f.vehicles) updateVehicle(d);
    for (const [id, link] of Object.entries(f.links)) {
      const v = vehicle(Number(id));
      const was = v.link && v.link.lost;
      v.link = link;
      if (was !== link.lost) styleMarker(v);
      // a lost vehicle heard flying: where it is predicted now, within error_m
      const pr = link.predicted;
      if (pr && !v.hidden) {
        if (!v.predCircle) v.predCircle = L.circle([pr.lat, pr.lon], { radius: pr.error_m, color: "#c00", weight: 1, dashArray: "2 4", fill: false, interactive: false }).addTo(layers.errors);
        v.predCircle.setLatLng([pr.lat, pr.lon]); v.predCircle.setRadius(pr.error_m);
      } else if (v.predCircle) { v.predCircle.remove(); v.predCircle = null; }
    }
    for (const id of f.dismissed || []) {
      const v = state.vehicles.get(id);
      if (!v) continue;
      for (const m of [v.marker, v.errCircle, v.predCircle, v.home, v.trailLine]) if (m) m.remove();
      if (v.row) v.row.row.remove();
      state.sel.delete(id);
      state.vehicles.delete(id); state.order = state.order.filter((x) => x !== id);
      if (state.focused === id) state.focused = null;
    }
    for (const [id, pts] of Object.entries(f.trails)) addTrail(Number(id), pts);
    for (const v of state.vehicles.values()) if (v.trail.length) trimTrail(v);
    if (f.alerts.length) renderAlerts(f.alerts);
    if (f.zones) renderZones(f.zones);
    if (f.missions) renderMissions(f.missions);
    if ("vote" in f) renderVote(f.vote);
    if (f.commands) renderCommands(f.commands);
    renderSummary(f.summary);
    renderList();
    renderIdList();
    if (state.focused !== null) renderPfd();
    if (f.replay) renderReplay(f.replay);
    if (!state.fitted && [...state.vehicles.values()].some((v) => v.data.has_position)) { state.fitted = true; fitAll(); }
    stats.frames++;
    keep(stats.applyMs, performance.now() - t0, 20000);  // the page's own work
    requestAnimationFrame(() => keep(stats.frameMs, performance.now() - t0, 20000));  // to the paint
  }

  function connect() {
    const proto = location.protocol === "https:" ? "wss" : "ws";
    const ws = new WebSocket(`${proto}://${location.host}/ws?token=${encodeURIComponent(TOKEN)}`);
    ws.binaryType = "arraybuffer";
    state.ws = ws;
    const decoder = new TextDecoder();
    ws.onopen = () => { $("status").textContent = `connected: ${state.config.mode === "replay" ? "replay" : "swarm " + state.config.swarm}`; };
    ws.onmessage = (e) => {
      if (typeof e.data !== "string") {
        stats.bytes += e.data.byteLength;
        apply(JSON.parse(decoder.decode(e.data)));
        return;
      }
      const m = JSON.parse(e.data);
      if (m.op === "answer" && state.pending.has(m.rid)) { state.pending.get(m.rid)(m); state.pending.delete(m.rid); }
    };
    ws.onclose = () => {
      $("status").textContent = "disconnected: reconnecting...";
      for (const r of state.pending.values()) r({ ok: false, error: "disconnected" });
      state.pending.clear();
      state.epoch = 0;
      setTimeout(connect, 1000);
    };
  }

  fetch(`/config?token=${encodeURIComponent(TOKEN)}`).then((r) => r.json()).then((config) => {
    state.config = config;
    state.trailS = config.trail_s;
    if (config.tiles) L.tileLayer(config.tiles, { maxZoom: 20, maxNativeZoom: 19 }).addTo(map);
    if (!config.commands) for (const e of document.querySelectorAll(".live-only")) e.classList.add("hidden");
    if (!TOKEN && config.commands) showError("no token in this page's URL: it shows the swarm but cannot command it");
    drawGrid();
    connect();
  });
})();
