/* convsynth viewer: plays the characters of window.CONVSYNTH_SCENE (scene.js, written by
   convsynth_jax/viewer/scene.py) in 3D with three.js (the global THREE), with their audio, an orbit
   camera, play / pause / scrub / speed and a timeline of the audio labels and synthetic transitions.
   The clock is the first audio element's while it plays (else the wall clock); ?t=SECONDS opens the
   page at that time. window.convsynthViewer is the page's interface (the browser tests use it). */
(function () {
  'use strict';
  var $ = function (id) { return document.getElementById(id); };
  var S = window.CONVSYNTH_SCENE;
  var KIND_COLORS = {PC: '#3a6fb0', LR: '#4f9a55', HP: '#c9862c'};

  function fail(msg) {
    var e = $('error');
    e.hidden = false;
    e.textContent = msg;
    $('status').textContent = 'error';
    document.body.dataset.state = 'error';
    if (window.console) { console.error('convsynth viewer: ' + msg); }
  }
  function warn(msg) {
    var e = $('error');
    e.hidden = false;
    e.textContent = (e.textContent ? e.textContent + '\n' : '') + msg;
    if (window.console) { console.warn('convsynth viewer: ' + msg); }
  }
  window.convsynthViewer = {ready: false};
  if (!S) { fail('The scene did not load (scene.js is missing or malformed).'); return; }
  if (S.error) { fail('Cannot show ' + (S.source || 'the input') + ': ' + S.error); return; }
  if (!window.THREE) { fail('three.js did not load (three.bundle.min.js).'); return; }
  if (!S.characters || !S.characters.length) { fail('The scene holds no characters.'); return; }

  var T = window.THREE, H = S.height, scale = S.scale, duration = S.duration;
  var stage = $('stage'), renderer;
  try {
    renderer = new T.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
  } catch (err) {
    fail('WebGL is not available in this browser (' + err.message + ').');
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  stage.appendChild(renderer.domElement);
  var scene = new T.Scene();
  scene.background = new T.Color('#eef0f4');
  scene.add(new T.HemisphereLight(0xffffff, 0x777066, 2.2));
  var sun = new T.DirectionalLight(0xffffff, 1.6);
  sun.position.set(H, 3 * H, 2 * H);
  scene.add(sun);

  // ------------------------------------------------------------------ bodies
  var up = new T.Vector3(0, 1, 0), va = new T.Vector3(), vb = new T.Vector3(), dir = new T.Vector3();
  var minY = Infinity;
  var chars = S.characters.map(function (c) {
    var P = c.positions, n = P.length;
    for (var i = 1; i < n; i += 3) { if (P[i] < minY) { minY = P[i]; } }
    var mat = new T.MeshLambertMaterial({color: new T.Color(c.color)});
    var skin = new T.MeshLambertMaterial({color: new T.Color('#e9c4a0')});
    var g = new T.Group();
    var torso = {};
    if (c.head !== null && c.head !== undefined) {      // root-to-head chain: thicker bones
      var parent = {};
      c.bones.forEach(function (b) { parent[b[1]] = b[0]; });
      for (var j = c.head; j !== undefined; j = parent[j]) { torso[j] = true; }
    }
    var cyl = new T.CylinderGeometry(1, 1, 1, 12);
    var bones = c.bones.map(function (b) {
      var r = (torso[b[1]] && torso[b[0]] ? 0.035 : 0.02) * H;
      var m = new T.Mesh(cyl, mat);
      m.userData.r = r;
      g.add(m);
      return {a: b[0], b: b[1], mesh: m};
    });
    var ball = new T.SphereGeometry(1, 16, 12);
    var joints = [];
    for (var k = 0; k < c.joints; k++) {
      var isHead = k === c.head, isHand = c.hands.indexOf(k) >= 0;
      var s = new T.Mesh(ball, isHead || isHand ? skin : mat);
      var r = (isHead ? 0.075 : isHand ? 0.032 : 0.024) * H;
      s.scale.set(r, r, r);
      g.add(s);
      joints.push(s);
    }
    scene.add(g);
    return {c: c, group: g, bones: bones, joints: joints, pose: new Float32Array(c.joints * 3)};
  });
  var grid = new T.GridHelper(8 * H, 16, 0x9a968e, 0xc8c5be);
  grid.position.y = minY * scale;
  scene.add(grid);

  function pose(ch, t) {               // joint positions at time t (linear between frames)
    var c = ch.c, J = c.joints, P = c.positions, x = Math.max(0, t * c.fps), f = Math.floor(x);
    var w = x - f;
    if (f >= c.frames - 1) { f = c.frames - 1; w = 0; }
    var o0 = f * J * 3, o1 = Math.min(f + 1, c.frames - 1) * J * 3, out = ch.pose;
    for (var i = 0; i < J * 3; i++) { out[i] = ((1 - w) * P[o0 + i] + w * P[o1 + i]) * scale; }
    return out;
  }
  function draw(t) {
    chars.forEach(function (ch) {
      var p = pose(ch, t), c = ch.c;
      ch.joints.forEach(function (s, j) {
        s.position.set(p[3 * j], p[3 * j + 1], p[3 * j + 2]);
      });
      if (c.head !== null && c.head !== undefined && c.bones.length) {   // head sphere above the neck joint
        var hb = ch.bones.filter(function (b) { return b.b === c.head; })[0];
        if (hb) {
          va.set(p[3 * hb.a], p[3 * hb.a + 1], p[3 * hb.a + 2]);
          vb.set(p[3 * c.head], p[3 * c.head + 1], p[3 * c.head + 2]);
          dir.subVectors(vb, va).normalize().multiplyScalar(0.06 * H);
          ch.joints[c.head].position.add(dir);
        }
      }
      ch.bones.forEach(function (b) {
        va.set(p[3 * b.a], p[3 * b.a + 1], p[3 * b.a + 2]);
        vb.set(p[3 * b.b], p[3 * b.b + 1], p[3 * b.b + 2]);
        dir.subVectors(vb, va);
        var len = dir.length(), m = b.mesh;
        m.visible = len > 1e-9;
        if (!m.visible) { return; }
        m.position.addVectors(va, vb).multiplyScalar(0.5);
        m.quaternion.setFromUnitVectors(up, dir.divideScalar(len));
        m.scale.set(m.userData.r, len, m.userData.r);
      });
    });
  }

  // ------------------------------------------------------------------ camera
  var camera = new T.PerspectiveCamera(35, 1, H / 50, H * 100);
  var controls = new T.OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;
  function centroid(ch) {
    var p = pose(ch, 0), v = new T.Vector3();
    for (var j = 0; j < ch.c.joints; j++) { v.x += p[3 * j]; v.y += p[3 * j + 1]; v.z += p[3 * j + 2]; }
    return v.divideScalar(ch.c.joints);
  }
  function resetCamera() {
    var cs = chars.map(centroid), center = new T.Vector3(), n = new T.Vector3(0, 0, 1), span = H;
    cs.forEach(function (v) { center.add(v); });
    center.divideScalar(cs.length);
    if (cs.length >= 2) {              // look across the line between the first two characters
      var d = new T.Vector3().subVectors(cs[1], cs[0]);
      d.y = 0;
      span = Math.max(H, d.length() + H);
      if (d.length() > 1e-6) { n.set(-d.z, 0, d.x).normalize(); }
    } else {
      var c = chars[0].c, p = pose(chars[0], 0);
      if (c.hands.length === 2) {      // in front of a single character: up x (right hand - left hand)
        var r = new T.Vector3(p[3 * c.hands[1]] - p[3 * c.hands[0]], 0, p[3 * c.hands[1] + 2] - p[3 * c.hands[0] + 2]);
        if (r.length() > 1e-6) { n.crossVectors(up, r).normalize(); }
      }
    }
    n.applyAxisAngle(up, 0.35);       // a three-quarter view
    // near enough that the bodies fill most of the height, far enough that the pair fits the width
    var dist = Math.max(1.35 * H, 1.2 * span / camera.aspect) / (2 * Math.tan(camera.fov * Math.PI / 360));
    function place(sign) {
      camera.position.copy(center).addScaledVector(n, sign * dist).addScaledVector(up, 0.35 * H);
      controls.target.copy(center);
      camera.lookAt(center);
      camera.updateMatrixWorld();
    }
    place(1);
    if (cs.length >= 2 && cs[0].clone().project(camera).x > cs[1].clone().project(camera).x) { place(-1); }
    controls.update();
  }

  // ------------------------------------------------------------------ audio and clock
  var audioBox = $('audio'), audios = (S.audio || []).map(function (a) {
    var el = document.createElement('audio');
    el.preload = 'auto';
    el.src = a.url;
    el.dataset.name = a.name;
    el.addEventListener('error', function () { warn('Cannot play the audio file ' + a.name + ' (' + a.url + ').'); });
    audioBox.appendChild(el);
    return el;
  });
  var master = audios[0] || null;
  var clock = {t: 0, playing: false, speed: 1, wall0: 0, t0: 0, source: 'wall'};
  function wall() { return performance.now() / 1000; }
  function now() {
    if (!clock.playing) { return clock.t; }
    if (master && !master.paused && !master.ended && master.readyState >= 2 && master.currentTime > 0) {
      clock.source = 'audio';
      clock.t0 = master.currentTime;
      clock.wall0 = wall();
      return master.currentTime;
    }
    clock.source = 'wall';
    return clock.t0 + (wall() - clock.wall0) * clock.speed;
  }
  function seek(t) {
    t = Math.max(0, Math.min(duration, +t || 0));
    clock.t = clock.t0 = t;
    clock.wall0 = wall();
    audios.forEach(function (el) {
      if (!isFinite(el.duration) || t < el.duration) { el.currentTime = t; } else { el.pause(); }
    });
    return t;
  }
  function play() {
    if (clock.t >= duration - 1e-3) { seek(0); }
    clock.playing = true;
    clock.t0 = clock.t;
    clock.wall0 = wall();
    audios.forEach(function (el) {
      el.playbackRate = clock.speed;
      if (!isFinite(el.duration) || clock.t < el.duration) {
        var pr = el.play();
        if (pr && pr.catch) { pr.catch(function (e) { $('status').textContent = 'audio blocked (' + e.name + '): playing without it'; }); }
      }
    });
    $('play').textContent = 'Pause';
  }
  function pause() {
    clock.t = now();
    clock.playing = false;
    audios.forEach(function (el) { el.pause(); });
    $('play').textContent = 'Play';
  }
  function setSpeed(v) {
    clock.t0 = now();
    clock.wall0 = wall();
    clock.speed = v;
    audios.forEach(function (el) { el.playbackRate = v; });
  }

  // ------------------------------------------------------------------ timeline
  var tl = $('timeline'), ROW = 14, LABEL = 120, RIGHT = 26, rows = [];
  chars.forEach(function (ch, k) {
    (S.kinds || ['PC', 'LR', 'HP']).forEach(function (kind) {
      rows.push({label: ch.c.name + ' ' + kind, color: KIND_COLORS[kind] || '#666',
                 spans: ch.c.labels.filter(function (l) { return l.kind === kind; })});
    });
    rows.push({label: ch.c.name + ' transitions', color: ch.c.color, ticks: ch.c.transitions});
  });
  function tx(t, w) { return LABEL + (w - LABEL - RIGHT) * (duration > 0 ? t / duration : 0); }
  function drawTimeline(t) {
    var dpr = window.devicePixelRatio || 1, w = tl.clientWidth || 600, h = ROW * rows.length + 18;
    if (tl.width !== Math.round(w * dpr) || tl.height !== Math.round(h * dpr)) {
      tl.width = Math.round(w * dpr);
      tl.height = Math.round(h * dpr);
      tl.style.height = h + 'px';
    }
    var g = tl.getContext('2d');
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    g.font = '11px system-ui, sans-serif';
    g.textBaseline = 'middle';
    rows.forEach(function (r, i) {
      var y = i * ROW;
      g.fillStyle = i % 2 ? '#f4f4f6' : '#e9eaee';
      g.fillRect(LABEL, y, w - LABEL - RIGHT, ROW);
      g.fillStyle = '#333';
      g.fillText(r.label, 4, y + ROW / 2);
      g.fillStyle = r.color;
      (r.spans || []).forEach(function (s) { g.fillRect(tx(s.start, w), y + 2, Math.max(1.5, tx(s.end, w) - tx(s.start, w)), ROW - 4); });
      (r.ticks || []).forEach(function (s) { g.fillRect(tx(s, w) - 0.75, y + 1, 1.5, ROW - 2); });
    });
    g.fillStyle = '#555';
    var step = duration > 60 ? 10 : duration > 20 ? 5 : 1;
    for (var s = 0; s <= duration + 1e-9; s += step) {
      g.fillRect(tx(s, w), rows.length * ROW, 1, 4);
      g.fillText(s + ' s', tx(s, w) + 2, rows.length * ROW + 11);
    }
    var x = tx(t, w);
    g.fillStyle = '#d62728';
    g.fillRect(x - 1, 0, 2, rows.length * ROW + 4);
    tl.dataset.cursor = t.toFixed(3);
    tl.dataset.cursorX = x.toFixed(1);
  }
  function timeAt(ev) {
    var r = tl.getBoundingClientRect(), w = tl.clientWidth;
    return Math.max(0, Math.min(duration, (ev.clientX - r.left - LABEL) / (w - LABEL - RIGHT) * duration));
  }
  var dragging = false;
  tl.addEventListener('mousedown', function (ev) { dragging = true; seek(timeAt(ev)); });
  window.addEventListener('mousemove', function (ev) { if (dragging) { seek(timeAt(ev)); } });
  window.addEventListener('mouseup', function () { dragging = false; });
  $('legend').textContent = chars.map(function (ch) { return ch.c.name; }).join(' · ') +
    ' — labels: PC phonemic clause, LR listener response, HP hesitation pause; ticks: synthetic transitions' +
    (audios.length ? '' : ' (no audio)');

  // ------------------------------------------------------------------ controls and loop
  var scrub = $('scrub');
  scrub.max = duration;
  scrub.step = 0.001;
  scrub.addEventListener('input', function () { seek(parseFloat(scrub.value)); });
  $('play').addEventListener('click', function () { if (clock.playing) { pause(); } else { play(); } });
  $('speed').addEventListener('change', function () { setSpeed(parseFloat($('speed').value)); });
  $('reset-camera').addEventListener('click', resetCamera);
  document.addEventListener('keydown', function (ev) {
    if (ev.key === ' ' && ev.target === document.body) { ev.preventDefault(); $('play').click(); }
  });
  function resize() {
    var w = stage.clientWidth || 800, h = stage.clientHeight || 450;
    renderer.setSize(w, h);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  window.addEventListener('resize', resize);
  var lastFrame = 0;
  function tick() {
    var t = now();
    if (t >= duration) { t = duration; if (clock.playing) { pause(); } clock.t = t; }
    if (clock.playing) {
      clock.t = t;
      audios.forEach(function (el) {       // the other audio files follow the clock
        if (el !== master && !el.paused && Math.abs(el.currentTime - t) > 0.08) { el.currentTime = t; }
      });
    }
    draw(t);
    controls.update();
    renderer.render(scene, camera);
    drawTimeline(t);
    if (document.activeElement !== scrub) { scrub.value = t; }
    $('clock').textContent = t.toFixed(2) + ' / ' + duration.toFixed(2) + ' s';
    lastFrame++;
    requestAnimationFrame(tick);
  }

  resize();
  resetCamera();
  var q = new URLSearchParams(window.location.search).get('t');
  if (q !== null && q !== '') {
    if (!isFinite(parseFloat(q))) { warn('?t=' + q + ' is not a time in seconds; starting at 0.'); } else { seek(parseFloat(q)); }
  }
  draw(clock.t);
  renderer.render(scene, camera);
  window.convsynthViewer = {
    ready: true, duration: duration, time: now, seek: function (t) { return seek(t); }, play: play, pause: pause,
    speed: setSpeed, playing: function () { return clock.playing; }, clockSource: function () { return clock.source; },
    frames: function () { return lastFrame; }, audio: audios, camera: camera, resetCamera: resetCamera,
    screen: function (k) {              // the screen box (CSS pixels) of character k's joints now
      var p = pose(chars[k], now()), v = new T.Vector3(), w = stage.clientWidth, h = stage.clientHeight;
      var box = [Infinity, Infinity, -Infinity, -Infinity];
      for (var j = 0; j < chars[k].c.joints; j++) {
        v.set(p[3 * j], p[3 * j + 1], p[3 * j + 2]).project(camera);
        var x = (v.x + 1) / 2 * w, y = (1 - v.y) / 2 * h;
        box = [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x), Math.max(box[3], y)];
      }
      return box;
    }
  };
  $('status').textContent = chars.length + ' character' + (chars.length > 1 ? 's' : '') + ', ' + duration.toFixed(2) + ' s' +
    (audios.length ? ', ' + audios.length + ' audio file' + (audios.length > 1 ? 's' : '') : ', no audio');
  document.body.dataset.state = 'ready';
  requestAnimationFrame(tick);
})();
