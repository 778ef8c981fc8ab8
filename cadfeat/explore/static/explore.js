// cadfeat explore: the page. Every number comes from the server (/api/evaluate: the study's own Python code);
// this script only draws. window.cadfeatExplore is the hook the browser test uses.
(function () {
  'use strict';
  var S = null, E = null, values = {}, pose = 0, showing = 'current';
  var inflight = false, pending = false, nEvals = 0;
  var $ = function (id) { return document.getElementById(id); };
  var COLOURS = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2', '#7f7f7f',
                 '#bcbd22', '#17becf'];
  function colour(j) { return COLOURS[j % COLOURS.length]; }
  function fmt(v, p) { return v === null || v === undefined ? '—' : Number(v).toPrecision(p || 6); }
  function post(route, body) {
    return fetch(route, {method: 'POST', headers: {'Content-Type': 'application/json'}, body: JSON.stringify(body)})
      .then(function (r) { return r.json().then(function (j) { if (!r.ok) throw new Error(j.error || r.status); return j; }); });
  }
  function message(text, error) { var m = $('message'); m.textContent = text; m.className = error ? 'error' : ''; }

  // ------------------------------------------------------------------------------------------ 3-D view
  var V = {}, C = {};
  function dec(list, T) { return new T([].concat.apply([], list)); }
  function setup3d() {
    var box = $('view3d');
    V.renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
    V.renderer.setPixelRatio(1);
    box.appendChild(V.renderer.domElement);
    V.scene = new THREE.Scene(); V.scene.background = new THREE.Color(0xf7f7f7);
    V.scene.add(new THREE.AmbientLight(0xffffff, 0.55));
    V.sun = new THREE.DirectionalLight(0xffffff, 0.7); V.scene.add(V.sun);
    V.part = new THREE.Mesh(geometry(S.mesh), new THREE.MeshLambertMaterial({color: 0xb8b8b8, side: THREE.DoubleSide}));
    V.scene.add(V.part);
    V.rings = new THREE.Group(); V.scene.add(V.rings);
    V.helpers = new THREE.Group(); V.scene.add(V.helpers);  // path + frusta: hidden in the camera view
    var path = S.T_part_cam.map(function (T) { return new THREE.Vector3(T[0][3], T[1][3], T[2][3]); });
    V.helpers.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(path),
                                 new THREE.LineBasicMaterial({color: 0x9467bd})));
    var bb = new THREE.Box3().setFromObject(V.part), ctr = bb.getCenter(new THREE.Vector3());
    V.size = bb.getSize(new THREE.Vector3()).length() || 1;
    var L = S.T_part_cam.length, seg = [];
    for (var q = 0; q < 5; q++) seg = seg.concat(frustum(Math.round(q * (L - 1) / 4)));
    V.helpers.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(seg),
                                         new THREE.LineBasicMaterial({color: 0x555555})));
    V.current = new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(frustum(0)),
                                       new THREE.LineBasicMaterial({color: 0xd62728}));
    V.helpers.add(V.current);
    V.cam = new THREE.PerspectiveCamera(35, 1, V.size * 0.01, V.size * 1000); V.cam.up.set(0, 0, 1);
    var all = bb.clone(); path.forEach(function (p) { all.expandByPoint(p); });  // frame part and path
    ctr = all.getCenter(new THREE.Vector3());
    var r = all.getSize(new THREE.Vector3()).length() * 0.5;
    V.cam.position.copy(ctr).add(new THREE.Vector3(1.2, -1.6, 1.0).normalize().multiplyScalar(r * 3.0));
    V.cam.lookAt(ctr);
    V.controls = new THREE.OrbitControls(V.cam, V.renderer.domElement);
    V.controls.target.copy(ctr); V.controls.update();
    V.controls.addEventListener('change', draw3d);
    // camera view: the same scene through the study camera (pinhole with K; distortion is in the ellipses)
    C.renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
    C.renderer.setPixelRatio(1);
    $('camview').insertBefore(C.renderer.domElement, $('camoverlay'));
    C.cam = new THREE.PerspectiveCamera(); C.cam.matrixAutoUpdate = false;
    resize();
    window.addEventListener('resize', function () { resize(); drawAll(); });
  }
  function geometry(mesh) {
    var geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(dec(mesh.vertices, Float32Array), 3));
    geo.setIndex(new THREE.BufferAttribute(dec(mesh.triangles, Uint32Array), 1));
    geo.computeVertexNormals();
    return geo;
  }
  function setMesh(mesh) { V.part.geometry.dispose(); V.part.geometry = geometry(mesh); }
  function frustum(k) {
    var T = S.T_part_cam[k], c = S.camera, d = 0.15 * V.size;
    var uv = [[0, 0], [c.width, 0], [c.width, c.height], [0, c.height]];
    var o = new THREE.Vector3(T[0][3], T[1][3], T[2][3]), q = uv.map(function (p) {
      var x = (p[0] - c.cx) / c.fx * d, y = (p[1] - c.cy) / c.fy * d, z = d;
      return new THREE.Vector3(T[0][0] * x + T[0][1] * y + T[0][2] * z + T[0][3],
                               T[1][0] * x + T[1][1] * y + T[1][2] * z + T[1][3],
                               T[2][0] * x + T[2][1] * y + T[2][2] * z + T[2][3]);
    });
    var seg = [];
    for (var i = 0; i < 4; i++) seg.push(o, q[i], q[i], q[(i + 1) % 4]);
    return seg;
  }
  function resize() {
    var b = $('view3d'), w = b.clientWidth, h = b.clientHeight;
    V.renderer.setSize(w, h); V.cam.aspect = w / h; V.cam.updateProjectionMatrix();
    var cb = $('camview'), cw = cb.clientWidth, ch = cb.clientHeight, c = S.camera;
    var scale = Math.min(cw / c.width, ch / c.height);
    C.w = Math.round(c.width * scale); C.h = Math.round(c.height * scale); C.scale = scale;
    C.renderer.setSize(C.w, C.h);
    var ov = $('camoverlay'); ov.width = C.w; ov.height = C.h; ov.style.width = C.w + 'px'; ov.style.height = C.h + 'px';
  }
  function updateRings() {
    V.rings.clear();
    E.holes.forEach(function (h, j) {
      var moved = !S.fixed[j];
      var ring = new THREE.Mesh(new THREE.TorusGeometry(h.radius, Math.max(h.radius * 0.15, V.size * 0.002), 8, 40),
                                new THREE.MeshBasicMaterial({color: S.fixed[j] ? 0x1f5fd6 : 0xff7f0e}));
      var a = new THREE.Vector3().fromArray(h.axis), c = new THREE.Vector3().fromArray(h.centre);
      ring.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), a.clone().normalize());
      ring.position.copy(c).addScaledVector(a, V.size * 0.001);
      ring.userData = {name: h.name, moved: moved};
      V.rings.add(ring);
    });
    V.current.geometry.setFromPoints(frustum(pose));
  }
  function draw3d() {
    V.sun.position.copy(V.cam.position);
    V.renderer.render(V.scene, V.cam);
  }
  function drawCamera() {
    var T = S.T_part_cam[pose], c = S.camera, n = V.size * 0.01, f = V.size * 1e4;
    // OpenCV camera (x right, y down, z forward) -> three.js camera (x right, y up, z backward)
    C.cam.matrixWorld.set(T[0][0], -T[0][1], -T[0][2], T[0][3], T[1][0], -T[1][1], -T[1][2], T[1][3],
                          T[2][0], -T[2][1], -T[2][2], T[2][3], 0, 0, 0, 1);
    C.cam.matrixWorldInverse.copy(C.cam.matrixWorld).invert();
    C.cam.projectionMatrix.set(2 * c.fx / c.width, 0, 1 - 2 * c.cx / c.width, 0,
                               0, 2 * c.fy / c.height, 2 * c.cy / c.height - 1, 0,
                               0, 0, -(f + n) / (f - n), -2 * f * n / (f - n), 0, 0, -1, 0);
    C.cam.projectionMatrixInverse.copy(C.cam.projectionMatrix).invert();
    V.helpers.visible = false;
    V.sun.position.set(T[0][3], T[1][3], T[2][3]);
    C.renderer.render(V.scene, C.cam);
    V.helpers.visible = true;
    var ctx = $('camoverlay').getContext('2d'), P = E.pose, s = C.scale;
    ctx.clearRect(0, 0, C.w, C.h);
    ctx.font = '11px sans-serif'; ctx.lineWidth = 1.5;
    E.holes.forEach(function (h, j) {
      var cp = P.centre_px[j], ax = P.axes_px[j], ang = P.angle_rad[j];
      if (!cp || !ax || cp[0] === null || ax[0] === null) return;
      ctx.strokeStyle = P.visible[j] ? '#2ca02c' : '#d62728';
      ctx.setLineDash(P.visible[j] ? [] : [4, 3]);
      ctx.beginPath();
      ctx.ellipse(cp[0] * s, cp[1] * s, Math.max(ax[0] * s / 2, 0.5), Math.max(ax[1] * s / 2, 0.5), ang || 0, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.fillStyle = ctx.strokeStyle; ctx.fillText(h.name, cp[0] * s + ax[0] * s / 2 + 2, cp[1] * s);
    });
    ctx.setLineDash([]);
  }

  // ----------------------------------------------------------------------------------------- plots
  function plot(canvas) {
    var key = canvas.dataset.measure, data = E.per_pose[key], t = S.times_s;
    var w = canvas.width = canvas.clientWidth, h = canvas.height = canvas.clientHeight, ctx = canvas.getContext('2d');
    var series = Array.isArray(data[0]) ? S.holes.map(function (_, j) { return data.map(function (r) { return r[j]; }); })
                                        : [data];
    var all = [].concat.apply([], series).filter(function (v) { return v !== null && isFinite(v); });
    var lo = Math.min.apply(null, all.concat([0])), hi = Math.max.apply(null, all.concat([0]));
    if (hi - lo < 1e-12) { hi += 1; lo -= 1; }
    var pad = {l: 44, r: 8, t: 16, b: 18}, t0 = t[0], t1 = t[t.length - 1] || 1;
    var X = function (v) { return pad.l + (v - t0) / ((t1 - t0) || 1) * (w - pad.l - pad.r); };
    var Y = function (v) { return h - pad.b - (v - lo) / (hi - lo) * (h - pad.t - pad.b); };
    ctx.clearRect(0, 0, w, h); ctx.font = '11px sans-serif'; ctx.fillStyle = '#333';
    ctx.fillText(canvas.dataset.title, pad.l, 11);
    ctx.fillText(fmt(hi, 3), 2, pad.t + 8); ctx.fillText(fmt(lo, 3), 2, h - pad.b);
    ctx.fillText('t = ' + fmt(t0, 2) + ' … ' + fmt(t1, 2) + ' s', w - 110, h - 4);
    ctx.strokeStyle = '#999'; ctx.beginPath(); ctx.moveTo(pad.l, Y(0)); ctx.lineTo(w - pad.r, Y(0)); ctx.stroke();
    ctx.strokeStyle = '#d62728'; ctx.beginPath(); ctx.moveTo(X(t[pose]), pad.t); ctx.lineTo(X(t[pose]), h - pad.b); ctx.stroke();
    series.forEach(function (s, j) {
      ctx.strokeStyle = series.length > 1 ? colour(j) : '#222'; ctx.beginPath();
      var up = false;
      s.forEach(function (v, k) {
        if (v === null || !isFinite(v)) { up = false; return; }
        if (up) ctx.lineTo(X(t[k]), Y(v)); else ctx.moveTo(X(t[k]), Y(v));
        up = true;
      });
      ctx.stroke();
    });
    if (series.length > 1) S.holes.forEach(function (n, j) { ctx.fillStyle = colour(j); ctx.fillText(n, w - pad.r - 30, pad.t + 10 + 11 * j); });
  }

  // ------------------------------------------------------------------------------------------ tables
  function tables() {
    var body = $('objectives').tBodies[0]; body.innerHTML = '';
    Object.keys(E.objectives).forEach(function (n) {
      var tr = document.createElement('tr'), v = E.objectives[n];
      tr.dataset.name = n; tr.dataset.value = String(v);
      tr.innerHTML = '<td>' + n + '</td><td class="value">' + fmt(v) + '</td><td>' + fmt(E.normalised[n], 4) + '</td>';
      body.appendChild(tr);
    });
    $('combined').textContent = E.combined === null ? '' : 'combined (' + S.combine + ', larger is better): ' + fmt(E.combined);
    $('combined').dataset.value = String(E.combined);
    var hb = $('holes').tBodies[0]; hb.innerHTML = '';
    S.holes.forEach(function (n, j) {
      var pp = E.per_pose, tr = document.createElement('tr');
      var cells = [pp.fov[pose][j], pp.focus[pose][j], pp.resolution_px[pose][j]];
      tr.innerHTML = '<td>' + n + (S.fixed[j] ? ' (fixed)' : '') + '</td>' + cells.map(function (v) {
        return '<td class="' + (v < 0 ? 'neg' : '') + '">' + fmt(v, 4) + '</td>'; }).join('') +
        '<td>' + (pp.visible[pose][j] ? 'yes' : 'no') + '</td>';
      hb.appendChild(tr);
    });
    $('pose-label').textContent = pose + ' (t = ' + fmt(S.times_s[pose], 3) + ' s)';
    $('which').textContent = showing === 'optimum' ? '(optimum of results.json)' : '';
  }
  function drawAll() {
    if (!E) return;
    updateRings(); draw3d(); drawCamera(); tables();
    Array.prototype.forEach.call(document.querySelectorAll('.plot[data-measure]'), plot);
    drawSweep();
  }
  // objectives along one design variable (thesis Figs. 5.10-5.11), fetched after the numbers, off the slider's path
  var SW = null, sweepKey = null, moved = null, nSweeps = 0;
  function requestSweep() {
    var name = moved || S.variables[0].name, others = {};
    Object.keys(values).forEach(function (k) { if (k !== name) others[k] = values[k]; });
    var key = name + JSON.stringify(others);
    if (key === sweepKey) { drawSweep(); return; }
    sweepKey = key;
    post('/api/sweep', {values: values, name: name}).then(function (r) {
      SW = r; nSweeps += 1; document.body.dataset.sweeps = String(nSweeps); drawSweep();
    }).catch(function (e) { message(String(e.message || e), true); });
  }
  function drawSweep() {
    var canvas = $('plot-sweep');
    if (!SW || !canvas) return;
    var w = canvas.width = canvas.clientWidth, h = canvas.height = canvas.clientHeight, ctx = canvas.getContext('2d');
    var xs = SW.x, series = Object.keys(SW.normalised).map(function (k) { return [k, SW.normalised[k]]; });
    if (SW.combined) series.push(['combined', SW.combined]);
    var all = [].concat.apply([], series.map(function (s) { return s[1]; })).filter(function (v) { return v !== null && isFinite(v); });
    var lo = Math.min.apply(null, all.concat([0])), hi = Math.max.apply(null, all.concat([1]));
    var pad = {l: 44, r: 90, t: 16, b: 18};
    var X = function (v) { return pad.l + (v - xs[0]) / ((xs[xs.length - 1] - xs[0]) || 1) * (w - pad.l - pad.r); };
    var Y = function (v) { return h - pad.b - (v - lo) / ((hi - lo) || 1) * (h - pad.t - pad.b); };
    ctx.clearRect(0, 0, w, h); ctx.font = '11px sans-serif';
    ctx.fillStyle = '#ddd';
    var step = (X(xs[1]) - X(xs[0])) || 2;
    SW.feasible.forEach(function (ok, k) { if (!ok) ctx.fillRect(X(xs[k]) - step / 2, pad.t, step, h - pad.t - pad.b); });
    ctx.fillStyle = '#333'; ctx.fillText(canvas.dataset.title.replace('the last moved variable', SW.name), pad.l, 11);
    ctx.fillText(fmt(hi, 3), 2, pad.t + 8); ctx.fillText(fmt(lo, 3), 2, h - pad.b);
    ctx.fillText(SW.name + ' = ' + fmt(xs[0], 4) + ' … ' + fmt(xs[xs.length - 1], 4), pad.l, h - 4);
    ctx.strokeStyle = '#d62728'; ctx.beginPath(); ctx.moveTo(X(values[SW.name]), pad.t); ctx.lineTo(X(values[SW.name]), h - pad.b); ctx.stroke();
    series.forEach(function (s, j) {
      ctx.strokeStyle = s[0] === 'combined' ? '#000' : colour(j); ctx.lineWidth = s[0] === 'combined' ? 2 : 1;
      ctx.beginPath();
      s[1].forEach(function (v, k) { if (v === null) return; if (k) ctx.lineTo(X(xs[k]), Y(v)); else ctx.moveTo(X(xs[k]), Y(v)); });
      ctx.stroke(); ctx.fillStyle = ctx.strokeStyle; ctx.fillText(s[0], w - pad.r + 6, pad.t + 10 + 12 * j);
    });
    ctx.lineWidth = 1;
  }

  // ----------------------------------------------------------------------------------- evaluation
  function evaluate() {
    if (inflight) { pending = true; return; }
    inflight = true; pending = false;
    document.body.dataset.state = 'busy';
    var sent = JSON.stringify(values), sentPose = pose;
    post('/api/evaluate', {values: values, pose: pose}).then(function (res) {
      E = res; tables();  // the numbers first ...
      $('status').textContent = 'scored in ' + (1000 * res.elapsed_s).toFixed(0) + ' ms (server)';
      if (JSON.stringify(values) === sent && pose === sentPose) nEvals += 1;
      document.body.dataset.evals = String(nEvals);
      return new Promise(function (done) {  // ... then the plots and both views, in the next frame
        requestAnimationFrame(function () { drawAll(); done(); });
      });
    }).catch(function (e) { message(String(e.message || e), true); }).then(function () {
      inflight = false;
      if (pending) evaluate(); else { document.body.dataset.state = 'idle'; requestSweep(); }
    });
  }
  function setValues(v) {
    Object.keys(v).forEach(function (n) {
      if (!(n in values)) return;
      values[n] = v[n];
      var el = document.querySelector('input[data-name="' + n + '"]');
      if (el) { el.value = v[n]; el.parentNode.parentNode.querySelector('.val').textContent = fmt(v[n]); }
    });
    evaluate();
  }
  function sliders() {
    var box = $('sliders');
    S.variables.forEach(function (v) {
      values[v.name] = v.value;
      var div = document.createElement('div'); div.className = 'slider';
      div.innerHTML = '<label>' + v.name + ' <span class="val"></span> ' + (v.unit || '') + ' <small>[' +
        fmt(v.lower, 4) + ', ' + fmt(v.upper, 4) + ']</small></label><div class="row"><input type="range"></div>';
      var el = div.querySelector('input');
      el.min = v.lower; el.max = v.upper; el.step = (v.upper - v.lower) / 1000; el.value = v.value;
      el.dataset.name = v.name;
      div.querySelector('.val').textContent = fmt(v.value);
      el.addEventListener('input', function () {
        values[v.name] = parseFloat(el.value); div.querySelector('.val').textContent = fmt(values[v.name]);
        moved = v.name; showing = 'current*'; evaluate();
      });
      box.appendChild(div);
    });
    var p = $('pose'); p.max = S.times_s.length - 1;
    p.addEventListener('input', function () { pose = parseInt(p.value, 10); evaluate(); });
    $('reset').addEventListener('click', function () { showing = 'current'; setValues(S.current); });
    var tog = $('toggle');
    if (S.optimum) {
      tog.disabled = false;
      tog.addEventListener('click', function () {
        showing = showing === 'optimum' ? 'current' : 'optimum';
        setValues(showing === 'optimum' ? S.optimum : S.current);
      });
    }
    $('save-start').addEventListener('click', function () {
      message('writing…');
      post('/api/save-start', {values: values}).then(function (r) { message('wrote ' + r.path); })
        .catch(function (e) { message(String(e.message || e), true); });
    });
    $('rebuild').addEventListener('click', function () {
      message('rebuilding the CAD model…');
      document.body.dataset.rebuilt = 'busy';
      post('/api/rebuild', {values: values}).then(function (r) {
        setMesh(r.mesh); drawAll(); message('rebuilt at this design (' + r.mesh.triangles.length + ' triangles)');
        document.body.dataset.rebuilt = String(r.mesh.triangles.length);
      }).catch(function (e) { message(String(e.message || e), true); document.body.dataset.rebuilt = 'error'; });
    });
    $('export').addEventListener('click', function () {
      message('rebuilding the CAD model…');
      post('/api/export', {values: values}).then(function (r) { message('exported ' + r.step + ' and ' + r.glb); })
        .catch(function (e) { message(String(e.message || e), true); });
    });
  }
  function snapshot(renderer) {
    var gl = renderer.getContext(), w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    var px = new Uint8Array(w * h * 4); gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    var n = w * h, s = 0, s2 = 0, hash = 0;
    for (var i = 0; i < px.length; i += 4) { var y = (px[i] + px[i + 1] + px[i + 2]) / 3; s += y; s2 += y * y;
      hash = (hash * 31 + px[i] + 7 * px[i + 1] + 13 * px[i + 2]) % 1000000007; }
    var m = s / n; return {width: w, height: h, mean: m, std: Math.sqrt(Math.max(s2 / n - m * m, 0)), hash: hash};
  }
  window.cadfeatExplore = {
    scene: function () { return S; }, last: function () { return E; }, sweep: function () { return SW; },
    snapshot3d: function () { draw3d(); return snapshot(V.renderer); },
    snapshotCamera: function () { drawCamera(); return snapshot(C.renderer); },
    overlayHash: function () { var d = $('camoverlay').getContext('2d').getImageData(0, 0, C.w, C.h).data, h = 0;
      for (var i = 0; i < d.length; i += 4) h = (h * 31 + d[i] + 7 * d[i + 1] + 13 * d[i + 3]) % 1000000007; return h; }
  };
  // the server answers at once and sets the study up meanwhile: show its progress until it is ready
  function setupText(st) {
    var cache = st.cache === 'hit' ? ' (read from the set-up cache' + (st.cache_saved_s ? '; it took ' +
      Math.round(st.cache_saved_s) + ' s to make' : '') + ')' : '';
    return st.phase + cache + ' — ' + Number(st.elapsed_s).toFixed(1) + ' s';
  }
  function loadScene() {
    fetch('/api/scene').then(function (r) { return r.json(); }).then(function (scene) {
      S = scene;
      $('study').textContent = S.study + ' — ' + S.part + ' (' + S.objectives.join(', ') + ', ' + S.aggregate + ')';
      setup3d(); sliders(); evaluate();
    }).catch(function (e) { message('could not load the study: ' + e, true); });
  }
  function waitForSetup() {
    fetch('/api/status').then(function (r) { return r.json(); }).then(function (st) {
      document.body.dataset.setup = st.state;
      if (st.state === 'ready') { $('status').textContent = 'study ready in ' + Number(st.ready_s).toFixed(1) + ' s' +
        (st.cache === 'hit' ? ' (set-up read from the cache)' : ''); loadScene(); return; }
      if (st.state === 'failed') { $('status').textContent = 'set-up failed'; message(st.error, true); return; }
      $('study').textContent = st.study;
      $('status').textContent = 'setting the study up: ' + setupText(st);
      setTimeout(waitForSetup, 250);
    }).catch(function (e) { message('the explorer stopped (see its terminal): ' + e, true); });
  }
  waitForSetup();
})();
