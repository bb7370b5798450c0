// The viewer of a zeroset HTML report: reads the JSON and the packed arrays embedded in the
// page, draws them with three.js (the global THREE, embedded before this script) and writes the
// numbers beside them. Nothing is fetched from the network.
"use strict";

(async () => {
  const THREE = window.THREE; // three.js and OrbitControls, from tools/viewer
  const report = JSON.parse(document.getElementById("zeroset-report").textContent);
  const packed = JSON.parse(document.getElementById("zeroset-layers").textContent);
  const TYPES = { float32: Float32Array, uint32: Uint32Array };
  // Five stops of viridis: dark where the data lie on the mesh, yellow where they are far.
  const RAMP = [[0.267, 0.005, 0.329], [0.231, 0.322, 0.545], [0.128, 0.567, 0.551],
    [0.369, 0.789, 0.383], [0.993, 0.906, 0.144]];

  async function unpack(entry) {
    const text = atob(entry.gzip);
    const bytes = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
    return new TYPES[entry.dtype](await new Response(stream).arrayBuffer());
  }

  function ramp(t) {
    const x = Math.min(Math.max(t, 0), 1) * (RAMP.length - 1);
    const i = Math.min(Math.floor(x), RAMP.length - 2);
    const f = x - i;
    return RAMP[i].map((a, k) => a + f * (RAMP[i + 1][k] - a));
  }

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
  let limit = null;
  const meshNames = Object.keys(packed).filter((name) => packed[name].faces);

  for (const name of meshNames) {
    const layer = packed[name];
    const geometry = new THREE.BufferGeometry();
    const vertices = await unpack(layer.vertices);
    geometry.setAttribute("position", new THREE.BufferAttribute(vertices, 3));
    geometry.setIndex(new THREE.BufferAttribute(await unpack(layer.faces), 1));
    geometry.computeVertexNormals();
    const group = new THREE.Group();
    const front = new THREE.MeshPhongMaterial({ color: 0x5a8cd9, side: THREE.FrontSide, flatShading: true });
    const back = new THREE.MeshPhongMaterial({ color: 0xd98c5a, side: THREE.BackSide, flatShading: true });
    group.add(new THREE.Mesh(geometry, front), new THREE.Mesh(geometry, back));
    if (layer.distance) {
      const distance = await unpack(layer.distance);
      limit = limit ?? percentile(distance, 0.95);
      const colours = new Float32Array(vertices.length);
      distance.forEach((d, i) => {
        colours.set(Number.isFinite(d) ? ramp(d / limit) : [0.6, 0.6, 0.6], 3 * i);
      });
      geometry.setAttribute("color", new THREE.BufferAttribute(colours, 3));
    }
    const boundary = await unpack(layer.boundary);
    const ends = new Float32Array(boundary.length * 3);
    boundary.forEach((v, i) => ends.set(vertices.subarray(3 * v, 3 * v + 3), 3 * i));
    const lines = new THREE.BufferGeometry();
    lines.setAttribute("position", new THREE.BufferAttribute(ends, 3));
    const edges = new THREE.LineSegments(lines, new THREE.LineBasicMaterial({ color: 0xd01010 }));
    edges.userData.boundary = true;
    group.add(edges);
    group.userData = { front, back, faces: layer.faces.shape[0], edges: boundary.length / 2 };
    objects[name + " mesh"] = group;
  }

  const first = objects[meshNames[0] + " mesh"].children[0].geometry;
  first.computeBoundingSphere();
  const { center, radius } = first.boundingSphere;

  if (packed.points) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(await unpack(packed.points), 3));
    const material = new THREE.PointsMaterial({ color: 0x222222, size: 2, sizeAttenuation: false });
    objects.points = new THREE.Points(geometry, material);
  }

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
  const state = {};
  function setLayer(name, on) {
    state[name] = on;
    if (name === "boundaries") {
      for (const mesh of meshNames) {
        objects[mesh + " mesh"].children.forEach((c) => { if (c.userData.boundary) c.visible = on; });
      }
    } else if (name === "colour by distance") {
      for (const mesh of meshNames) {
        const { front, back } = objects[mesh + " mesh"].userData;
        for (const material of [front, back]) {
          material.vertexColors = on;
          material.color.set(on ? 0xffffff : material === front ? 0x5a8cd9 : 0xd98c5a);
          material.needsUpdate = true;
        }
      }
      legend.hidden = !on;
    } else {
      objects[name].visible = on;
    }
    const box = document.querySelector(`input[data-layer="${name}"]`);
    if (box) box.checked = on;
    draw();
  }

  const legend = document.getElementById("legend");
  legend.hidden = true;
  if (limit !== null) {
    legend.innerHTML = `<div>distance from the data to the mesh</div><div class="bar"></div>`
      + `<div>0 &ndash; ${limit.toPrecision(3)} (95 %) and more</div>`;
  }
  const form = document.getElementById("layers");
  const last = meshNames[meshNames.length - 1] + " mesh";
  const switches = [
    ...Object.keys(objects).map((name) => [name, name === last]),
    ["boundaries", true],
    ...(limit !== null ? [["colour by distance", false]] : []),
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

  function section(title, rows, note) {
    const h = document.createElement("h2");
    h.textContent = title;
    const table = document.createElement("table");
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
