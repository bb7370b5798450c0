// The viewer of a zeroset HTML report: reads the JSON and the packed arrays embedded in the
// page, draws them with three.js (the global THREE, embedded before this script) and writes the
// numbers beside them: a reconstruction's, a pipe inspection's, or both. Nothing is fetched
// from the network.
"use strict";

(async () => {
  const THREE = window.THREE; // three.js and OrbitControls, from tools/viewer
  const report = JSON.parse(document.getElementById("zeroset-report").textContent);
  const packed = JSON.parse(document.getElementById("zeroset-layers").textContent);
  const TYPES = { float32: Float32Array, uint32: Uint32Array };
  // Five stops of viridis: dark where the data lie on the mesh, yellow where they are far.
  const VIRIDIS = [[0.267, 0.005, 0.329], [0.231, 0.322, 0.545], [0.128, 0.567, 0.551],
    [0.369, 0.789, 0.383], [0.993, 0.906, 0.144]];
  // Seven stops of matplotlib's RdBu_r, as in zeroset.inspect's pictures: blue inward, white
  // on the nominal wall, red outward.
  const DIVERGING = [[0.020, 0.188, 0.380], [0.216, 0.514, 0.733], [0.655, 0.814, 0.894],
    [0.969, 0.966, 0.965], [0.969, 0.718, 0.600], [0.789, 0.277, 0.255], [0.404, 0.0, 0.122]];
  const GREY = [0.6, 0.6, 0.6]; // where a value is unknown (NaN)
  const FRONT = 0x5a8cd9, BACK = 0xd98c5a;

  async function unpack(entry) {
    const text = atob(entry.gzip);
    const bytes = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
    return new TYPES[entry.dtype](await new Response(stream).arrayBuffer());
  }

  function ramp(stops, t) {
    const x = Math.min(Math.max(t, 0), 1) * (stops.length - 1);
    const i = Math.min(Math.floor(x), stops.length - 2);
    const f = x - i;
    return stops[i].map((a, k) => a + f * (stops[i + 1][k] - a));
  }

  // Per-vertex colours of `values`, `colour(value)` where finite and grey elsewhere.
  function paint(values, colour) {
    const colours = new Float32Array(3 * values.length);
    values.forEach((v, i) => colours.set(Number.isFinite(v) ? colour(v) : GREY, 3 * i));
    return new THREE.BufferAttribute(colours, 3);
  }

  const mm = (metres, digits = 1) => (1000 * metres).toFixed(digits);

  function percentile(values, q) {
    const known = Array.from(values).filter(Number.isFinite).sort((a, b) => a - b);
    return known.length ? known[Math.min(known.length - 1, Math.floor(q * known.length))] : 1;
  }

  // ---------------------------------------------------------------- scene
  const canvas = document.getElementById("canvas");
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xffffff);
  const camera = new THREE.PerspectiveCamera(30, 1, 1e-3, 1e3);
  camera.up.set(0, 0, 1);
  scene.add(camera);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 0.9));
  const headlight = new THREE.DirectionalLight(0xffffff, 1.3);
  headlight.position.set(0.3, 0.5, 1);
  camera.add(headlight);

  const objects = {};
  const legends = {}; // the HTML legend of each colouring some mesh has, by its switch
  let limit = null; // of the distances: the first mesh's 95th percentile, for every mesh
  const meshNames = Object.keys(packed).filter((name) => packed[name].faces);

  for (const name of meshNames) {
    const layer = packed[name];
    const geometry = new THREE.BufferGeometry();
    const vertices = await unpack(layer.vertices);
    geometry.setAttribute("position", new THREE.BufferAttribute(vertices, 3));
    geometry.setIndex(new THREE.BufferAttribute(await unpack(layer.faces), 1));
    geometry.computeVertexNormals();
    const group = new THREE.Group();
    const front = new THREE.MeshPhongMaterial({ color: FRONT, side: THREE.FrontSide, flatShading: true });
    const back = new THREE.MeshPhongMaterial({ color: BACK, side: THREE.BackSide, flatShading: true });
    group.add(new THREE.Mesh(geometry, front), new THREE.Mesh(geometry, back));
    const colours = {};
    if (layer.distance) {
      const distance = await unpack(layer.distance);
      limit = limit ?? percentile(distance, 0.95);
      colours["colour by distance"] = paint(distance, (d) => ramp(VIRIDIS, d / limit));
    }
    if (layer.deviation) {
      // Signed metres from the nominal pipe, symmetric about 0 up to the 99th percentile.
      const deviation = await unpack(layer.deviation);
      const reach = Math.max(percentile(deviation.map(Math.abs), 0.99), 1e-9);
      colours["colour by deviation"] = paint(
        deviation, (d) => ramp(DIVERGING, 0.5 + 0.5 * d / reach));
      const shown = Number((1000 * reach).toPrecision(2));
      legends["colour by deviation"] = `<div>deviation: blue &minus;${shown} mm (inward)`
        + ` &hellip; red +${shown} mm (outward)</div><div class="bar diverging"></div>`;
    }
    const boundary = await unpack(layer.boundary);
    const ends = new Float32Array(boundary.length * 3);
    boundary.forEach((v, i) => ends.set(vertices.subarray(3 * v, 3 * v + 3), 3 * i));
    const lines = new THREE.BufferGeometry();
    lines.setAttribute("position", new THREE.BufferAttribute(ends, 3));
    const edges = new THREE.LineSegments(lines, new THREE.LineBasicMaterial({ color: 0xd01010 }));
    edges.userData.boundary = true;
    group.add(edges);
    group.userData = {
      geometry, front, back, colours, faces: layer.faces.shape[0], edges: boundary.length / 2,
    };
    objects[name + " mesh"] = group;
  }

  const first = objects[meshNames[0] + " mesh"].children[0].geometry;
  first.computeBoundingSphere();
  const { center, radius } = first.boundingSphere;

  if (limit !== null) {
    legends["colour by distance"] = `<div>distance from the data to the mesh</div>`
      + `<div class="bar"></div><div>0 &ndash; ${limit.toPrecision(3)} (95 %) and more</div>`;
  }

  if (packed.points) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(await unpack(packed.points), 3));
    const material = new THREE.PointsMaterial({ color: 0x222222, size: 2, sizeAttenuation: false });
    objects.points = new THREE.Points(geometry, material);
  }

  if (packed.normals) {
    const origins = await unpack(packed.normals.origins);
    const directions = await unpack(packed.normals.directions);
    const tips = new Float32Array(origins.length * 2);
    for (let i = 0; i < origins.length; i += 3) {
      for (let k = 0; k < 3; k++) {
        tips[2 * i + k] = origins[i + k];
        tips[2 * i + 3 + k] = origins[i + k] + 0.03 * radius * directions[i + k];
      }
    }
    const normalLines = new THREE.BufferGeometry();
    normalLines.setAttribute("position", new THREE.BufferAttribute(tips, 3));
    objects.normals = new THREE.LineSegments(
      normalLines, new THREE.LineBasicMaterial({ color: 0x1a9933 }));
  }

  for (const object of Object.values(objects)) scene.add(object);

  const controls = new THREE.OrbitControls(camera, canvas);
  controls.target.copy(center);
  camera.position.copy(center).add(new THREE.Vector3(1.6, -2.8, 1.6).multiplyScalar(radius * 1.2));
  camera.near = radius / 100;
  camera.far = radius * 100;
  controls.update();

  function draw() {
    const width = canvas.clientWidth, height = canvas.clientHeight;
    if (canvas.width !== Math.floor(width * renderer.getPixelRatio())) {
      renderer.setSize(width, height, false);
      camera.aspect = width / Math.max(height, 1);
      camera.updateProjectionMatrix();
    }
    renderer.render(scene, camera);
  }
  controls.addEventListener("change", draw);
  new ResizeObserver(draw).observe(canvas);

  // ---------------------------------------------------------------- layer switches
  // Colour every mesh by the colouring switched `on` (a key of `legends`), or plainly for null
  // and where a mesh lacks it.
  let painted = null;
  function colour(on) {
    painted = on;
    for (const mesh of meshNames) {
      const { geometry, front, back, colours } = objects[mesh + " mesh"].userData;
      const attribute = colours[on];
      if (attribute) geometry.setAttribute("color", attribute);
      for (const material of [front, back]) {
        material.vertexColors = Boolean(attribute);
        material.color.set(attribute ? 0xffffff : material === front ? FRONT : BACK);
        material.needsUpdate = true;
      }
    }
    legend.innerHTML = legends[on] ?? "";
    legend.hidden = !legends[on];
  }

  const state = {};
  function setLayer(name, on) {
    state[name] = on;
    if (name === "boundaries") {
      for (const mesh of meshNames) {
        objects[mesh + " mesh"].children.forEach((c) => { if (c.userData.boundary) c.visible = on; });
      }
    } else if (name in legends) { // one colouring at a time
      if (on && painted !== null && painted !== name) setLayer(painted, false);
      if (on || painted === name) colour(on ? name : null);
    } else {
      objects[name].visible = on;
    }
    const box = document.querySelector(`input[data-layer="${name}"]`);
    if (box) box.checked = on;
    draw();
  }

  const legend = document.getElementById("legend");
  legend.hidden = true;
  const form = document.getElementById("layers");
  const last = meshNames[meshNames.length - 1] + " mesh";
  const switches = [
    ...Object.keys(objects).map((name) => [name, name === last]),
    ["boundaries", true],
    ...["colour by distance", "colour by deviation"].filter((name) => name in legends)
      .map((name) => [name, name === "colour by deviation"]),
  ];
  for (const [name, on] of switches) {
    const label = document.createElement("label");
    const box = document.createElement("input");
    box.type = "checkbox";
    box.dataset.layer = name;
    box.addEventListener("change", () => setLayer(name, box.checked));
    label.append(box, " " + name);
    form.append(label);
    setLayer(name, on);
  }

  // ---------------------------------------------------------------- numbers
  const numbers = document.getElementById("numbers");
  const fmt = (v) => (typeof v === "number" ? (Number.isInteger(v) ? v.toLocaleString("en")
    : v.toPrecision(4)) : v === null || v === undefined ? "" : String(v));

  function section(title, rows, note, head) {
    const h = document.createElement("h2");
    h.textContent = title;
    const table = document.createElement("table");
    if (head) {
      const tr = table.createTHead().insertRow();
      for (const name of head) {
        const th = document.createElement("th");
        th.textContent = name;
        tr.append(th);
      }
    }
    for (const row of rows) {
      const tr = table.insertRow();
      row.forEach((cell, i) => {
        const td = tr.insertCell();
        td.textContent = fmt(cell);
        if (i > 0 && typeof cell === "number") td.className = "n";
      });
    }
    numbers.append(h, table);
    if (note) numbers.append(note);
    return table;
  }

  function list(items) {
    const ul = document.createElement("ul");
    for (const item of items) {
      const li = document.createElement("li");
      li.textContent = item;
      ul.append(li);
    }
    return ul;
  }

  if (report.inspection) {
    const n = report.inspection;
    const clock = (item) => `${item.clock.toFixed(0)}\u00b0\u00a0(${item.clock_time})`;
    const spread = (s, digits) => (s === null ? "not measured"
      : [s.min, s.median, s.max].map((v) => v.toFixed(digits)).join(" / "));
    const extent = n.extent === null ? "the data\u2019s extent not measured"
      : `the data extend ${n.extent.toFixed(2)} m`;
    const warn = (table, row) => table.rows[row].classList.add("warn");
    const summary = section("Inspection", [
      ["nominal diameter", `${mm(n.nominal_diameter)} mm`],
      ["measured diameter", `${mm(n.measured_diameter)} mm`],
      ["centreline", `fitted ${n.length.toFixed(2)} m; ${extent}` + (n.length_agrees === false
        ? " \u26a0 they differ by more than 2 % or one diameter: check the centreline" : "")],
      ["defect threshold", `${n.threshold_mm.toFixed(2)} mm`],
      ["defects", n.defects.length], ["joints", n.joints.length],
      ["branches", n.branches.length],
    ], n.threshold_basis ? list([`threshold: ${n.threshold_basis}`]) : null);
    if (n.length_agrees === false) warn(summary, 2);
    const s = n.stations;
    section(`Stations: min / median / max over ${s.count}`, [
      ["ovality (D_max \u2212 D_min) / D_nominal", `${spread(s.ovality_percent, 2)} %`],
      ["D_min", `${spread(s.d_min_mm, 1)} mm`], ["D_mean", `${spread(s.d_mean_mm, 1)} mm`],
      ["D_max", `${spread(s.d_max_mm, 1)} mm`],
    ]);
    if (n.unreliable.length) {
      section("Unreliable stretches (no defect judged there)", n.unreliable.map((u) => [
        `${u.axial_start.toFixed(3)}\u2013${u.axial_end.toFixed(3)}`, u.reason,
      ]), null, ["axial m", "the fit does not explain the sections"]);
    }
    if (n.defects.length) {
      const table = section("Defects", n.defects.map((d) => [
        d.number, d.kind, d.axial.toFixed(3), clock(d),
        `${mm(d.depth)} \u00b1 ${d.uncertainty === null ? "?" : mm(d.uncertainty)}`,
        d.depth_percent === null ? "" : d.depth_percent.toFixed(1),
        d.assess ? "> 6 % D, assess" : "",
        `${d.axial_start.toFixed(3)}\u2013${d.axial_end.toFixed(3)}`, mm(d.width, 0),
        (1e4 * d.area).toFixed(1),
      ]), null, ["#", "kind", "axial m", "clock", "depth mm", "depth % D", "B31.8",
        "axial extent m", "width mm", "area cm\u00b2"]);
      n.defects.forEach((d, i) => { if (d.assess) warn(table, i + 1); });
    }
    if (n.joints.length) {
      const opt = (v, digits) => (v === null ? "" : v.toFixed(digits));
      section("Joints", n.joints.map((j) => [
        j.number, j.kind, j.axial_m.toFixed(3),
        `${opt(j.size_mm, 1)} \u00b1 ${j.uncertainty_mm === null ? "?" : opt(j.uncertainty_mm, 1)}`,
        j.clock === null ? "" : `${j.clock_deg.toFixed(0)}\u00b0\u00a0(${j.clock})`,
        opt(j.depth_mm, 1),
      ]), null, ["#", "kind", "axial m", "size mm", "offset towards", "gap depth mm"]);
    }
    if (n.branches.length) {
      section("Branches", n.branches.map((b, i) => [
        i + 1, b.axial.toFixed(3), clock(b), (1e4 * b.area).toFixed(1),
      ]), null, ["#", "axial m", "clock", "opening cm\u00b2"]);
    }
  }
  if (report.stats) {
    const s = report.stats;
    section("Mesh", [
      ["vertices", s.vertices], ["triangles", s.faces], ["boundary loops", s.boundary_loops],
      ["components", s.mesh_components], ["Euler characteristic", s.euler_characteristic],
      ["contouring", report.config.contour],
    ]);
    section("Points", [
      ["read", s.input_points], ["outliers dropped", s.outliers],
      ["fitted by tangent planes", s.phase1_points],
      ...(s.phase2_points !== undefined ? [["used by phase 2", s.phase2_points]] : []),
      ["orientation components", s.orientation_components],
      ["grid vertices evaluated", s.grid_vertices], ["of them undefined", s.undefined_grid_vertices],
    ]);
    const p = report.parameters;
    section("Parameters", [
      ["rho + delta", p.rho_delta], ["cube size", p.cube_size], ["spacing", p.spacing],
      ["noise", p.noise], ["averaging cell", p.averaging_cell],
    ], list(p.notes));
    if (report.fit) {
      const f = report.fit;
      section("Distance from the points to the mesh", [
        ["mean", f.distance.mean], ["median", f.distance.median], ["95 %", f.distance.p95],
        ["max", f.distance.max], [`within ${fmt(f.tau)}`, `${(100 * f.coverage).toFixed(1)} %`],
      ]);
    }
    section("Seconds", [
      ...Object.entries(report.timings), ["total", report.total_seconds],
    ]);
    if (report.optimization) {
      const o = report.optimization;
      section("Phase 2: energy", ["distance", "representation", "spring", "total"].map(
        (k) => [k, o.energy_before[k], o.energy[k]]));
      section("Phase 2: moves (accepted of tried)", Object.entries(o.moves).map(
        ([kind, c]) => [kind, c.accepted, Object.values(c).reduce((a, b) => a + b, 0)]));
      const h = document.createElement("h2");
      h.textContent = "Phase 2: energy at each step";
      numbers.append(h, chart(o.history.map((e) => e.total)));
    }
  }

  function chart(values) {
    const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
    const lo = Math.min(...values), hi = Math.max(...values);
    svg.setAttribute("viewBox", "0 0 400 160");
    const points = values.map((v, i) => `${10 + 380 * i / Math.max(values.length - 1, 1)},`
      + `${150 - 140 * (v - lo) / Math.max(hi - lo, 1e-300)}`).join(" ");
    svg.innerHTML = `<polyline fill="none" stroke="#24476b" stroke-width="2" points="${points}"/>`
      + `<text x="12" y="14" font-size="11">${fmt(hi)}</text>`
      + `<text x="12" y="156" font-size="11">${fmt(lo)}</text>`;
    return svg;
  }

  draw();
  window.zerosetViewer = { ready: true, layers: switches.map(([name]) => name), setLayer, draw };
})().catch((error) => {
  console.error(error);
  document.body.dataset.error = String(error);
});
