// The interactive before/after view of report.html (cadfeat/report/view3d.py inlines it after three.js).
(function () {
  var S = JSON.parse(document.getElementById('view3d-data').textContent);
  var box = document.getElementById('view3d');
  function dec(b64, T) { var s = atob(b64), u = new Uint8Array(s.length);
    for (var i = 0; i < s.length; i++) u[i] = s.charCodeAt(i); return new T(u.buffer); }
  var renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
  renderer.setPixelRatio(1);
  box.appendChild(renderer.domElement);
  var scene = new THREE.Scene(); scene.background = new THREE.Color(0xf7f7f7);
  var cam = new THREE.PerspectiveCamera(35, 1, 0.1, 1e6); cam.up.set(0, 0, 1);
  scene.add(new THREE.AmbientLight(0xffffff, 0.55));
  var sun = new THREE.DirectionalLight(0xffffff, 0.7); scene.add(sun);
  var groups = {}, pickables = {}, labels = {};
  var colours = {before: 0xb0b0b0, after: 0xc8c0a8};
  Object.keys(S.designs).forEach(function (which) {
    var d = S.designs[which], g = new THREE.Group();
    var geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(dec(d.vertices, Float32Array), 3));
    geo.setIndex(new THREE.BufferAttribute(dec(d.triangles, Uint32Array), 1));
    geo.computeVertexNormals();
    g.add(new THREE.Mesh(geo, new THREE.MeshLambertMaterial({color: colours[which], side: THREE.DoubleSide})));
    pickables[which] = []; labels[which] = [];
    d.holes.forEach(function (h) {
      var colour = h.fixed ? 0x1f5fd6 : !h.changed ? 0x333333 : (which === 'after' ? 0x2ca02c : 0xff7f0e);
      var ring = new THREE.Mesh(new THREE.TorusGeometry(h.radius, Math.max(h.radius * 0.12, S.scale * 0.002), 8, 40),
                                new THREE.MeshBasicMaterial({color: colour}));
      var a = new THREE.Vector3().fromArray(h.axis), c = new THREE.Vector3().fromArray(h.centre);
      ring.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), a.clone().normalize());
      ring.position.copy(c).addScaledVector(a, S.scale * 0.001);
      var pick = new THREE.Mesh(new THREE.SphereGeometry(h.radius * 1.2, 12, 8),
                                new THREE.MeshBasicMaterial({visible: false}));
      pick.position.copy(c); pick.userData = h;
      g.add(ring); g.add(pick); pickables[which].push(pick);
      var el = document.createElement('div'); el.className = 'lbl'; el.textContent = h.name;
      el.style.display = 'none'; box.appendChild(el); labels[which].push({el: el, p: c});
    });
    scene.add(g); groups[which] = g;
  });
  if (S.camera && S.camera.path && S.camera.path.length > 1) {
    var pts = S.camera.path.map(function (p) { return new THREE.Vector3().fromArray(p); });
    scene.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(pts),
                             new THREE.LineBasicMaterial({color: 0x9467bd})));
    var seg = [];
    (S.camera.frusta || []).forEach(function (f) {
      var o = new THREE.Vector3().fromArray(f.apex), q = f.corners.map(function (p) { return new THREE.Vector3().fromArray(p); });
      for (var i = 0; i < 4; i++) { seg.push(o, q[i], q[i], q[(i + 1) % 4]); }
    });
    scene.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(seg),
                                     new THREE.LineBasicMaterial({color: 0x444444})));
  }
  // frame the part (the camera path may be far away: zoom out with the wheel)
  var bb = new THREE.Box3().setFromObject(groups.after || groups.before), ctr = bb.getCenter(new THREE.Vector3());
  var r = bb.getSize(new THREE.Vector3()).length() * 0.5 || 1;
  var controls = new THREE.OrbitControls(cam, renderer.domElement);
  controls.target.copy(ctr);
  cam.position.copy(ctr).add(new THREE.Vector3(1.2, -1.6, 1.4).multiplyScalar(r * 1.6));
  cam.near = r * 0.01; cam.far = r * 1000; cam.lookAt(ctr); controls.update();
  var current = groups.after ? 'after' : 'before';
  var home = {pos: cam.position.clone(), target: controls.target.clone()};
  function frame(all) {  // the part alone, or the part and the camera path
    var b = new THREE.Box3().setFromObject(all ? scene : groups[current]);
    var c = b.getCenter(new THREE.Vector3()), rr = b.getSize(new THREE.Vector3()).length() * 0.5 || 1;
    if (!all) { cam.position.copy(home.pos); controls.target.copy(home.target); }
    else { controls.target.copy(c); cam.position.copy(c).add(new THREE.Vector3(1.2, -1.6, 1.4).multiplyScalar(rr * 1.4)); }
    controls.update(); draw();
  }
  var info = document.getElementById('view3d-info');
  function fmt(v) { return typeof v === 'number' ? (Math.abs(v) >= 1e4 || (v !== 0 && Math.abs(v) < 1e-3) ? v.toExponential(3) : (+v.toPrecision(4)).toString()) : String(v); }
  function showInfo(h) {
    if (!h) { info.style.display = 'none'; return; }
    var rows = ['<b>' + h.name.replace(/[&<>"]/g, '') + '</b> (' + current + ')', 'Ø ' + fmt(2 * h.radius) + ' mm' + (h.fixed ? ', fixed' : '')];
    Object.keys(h.measures).forEach(function (k) { rows.push(k + ': ' + fmt(h.measures[k])); });
    info.innerHTML = rows.join('<br>'); info.style.display = 'block';
  }
  function resize() { var w = box.clientWidth, hgt = box.clientHeight; renderer.setSize(w, hgt, false);
    cam.aspect = w / hgt; cam.updateProjectionMatrix(); }
  function draw() {
    sun.position.copy(cam.position);
    renderer.render(scene, cam);
    var w = box.clientWidth, hgt = box.clientHeight;
    Object.keys(labels).forEach(function (which) {
      labels[which].forEach(function (l) {
        if (which !== current) { l.el.style.display = 'none'; return; }
        var p = l.p.clone().project(cam);
        l.el.style.display = p.z < 1 ? 'block' : 'none';
        l.el.style.left = ((p.x + 1) / 2 * w + 6) + 'px'; l.el.style.top = ((1 - p.y) / 2 * hgt - 18) + 'px';
      });
    });
  }
  function show(which) {
    if (!groups[which]) return;
    current = which;
    Object.keys(groups).forEach(function (k) { groups[k].visible = k === which; });
    document.querySelectorAll('#view3d input[name=view3d-which]').forEach(function (b) { b.checked = b.value === which; });
    showInfo(null); draw();
  }
  var ray = new THREE.Raycaster(), mouse = new THREE.Vector2();
  function pickAt(ev) {
    var rect = renderer.domElement.getBoundingClientRect();
    mouse.set((ev.clientX - rect.left) / rect.width * 2 - 1, -(ev.clientY - rect.top) / rect.height * 2 + 1);
    ray.setFromCamera(mouse, cam);
    var hit = ray.intersectObjects(pickables[current], false)[0];
    return hit ? hit.object.userData : null;
  }
  renderer.domElement.addEventListener('pointermove', function (ev) { var h = pickAt(ev); if (h) showInfo(h); });
  renderer.domElement.addEventListener('click', function (ev) { showInfo(pickAt(ev)); });
  document.querySelectorAll('#view3d input[name=view3d-which]').forEach(function (b) {
    b.addEventListener('change', function () { show(b.value); });
  });
  document.getElementById('view3d-fit').addEventListener('click', function () { frame(true); });
  document.getElementById('view3d-part').addEventListener('click', function () { frame(false); });
  controls.addEventListener('change', draw);
  window.addEventListener('resize', function () { resize(); draw(); });
  resize(); show(current);
  window.cadfeat3d = {
    show: show, which: function () { return current; }, frame: frame,
    screen: function (i) {  // client (x, y) of hole i of the design shown
      var rect = renderer.domElement.getBoundingClientRect(), p = labels[current][i].p.clone().project(cam);
      return [rect.left + (p.x + 1) / 2 * rect.width, rect.top + (1 - p.y) / 2 * rect.height];
    },
    snapshot: function () {
      draw();
      var gl = renderer.getContext(), w = gl.drawingBufferWidth, hgt = gl.drawingBufferHeight;
      var px = new Uint8Array(w * hgt * 4); gl.readPixels(0, 0, w, hgt, gl.RGBA, gl.UNSIGNED_BYTE, px);
      var n = w * hgt, s = 0, s2 = 0, h = 0;
      for (var i = 0; i < px.length; i += 4) { var y = (px[i] + px[i + 1] + px[i + 2]) / 3; s += y; s2 += y * y;
        h = (h * 31 + px[i] + 7 * px[i + 1] + 13 * px[i + 2]) % 1000000007; }
      var m = s / n; return {width: w, height: hgt, mean: m, std: Math.sqrt(Math.max(s2 / n - m * m, 0)), hash: h};
    }
  };
})();
