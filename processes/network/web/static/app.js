// The match in 3D: the table, the net (a panel; a cloth net's knots as line segments of its mesh
// once net messages come, shown when their tick comes up), both bats, the ball and its shadow, the score, the
// server, a banner with each point's reason; an orbit camera, a broadcast side camera and each
// player's view. Drawn at the display's refresh rate, 100 ms behind the snapshots and
// interpolated between them, as `pingpong join --as spectator` shows them. A browser may play a
// seat: its keys (those of `pingpong join`) and pointer go to the bridge, which plays the seat
// through a player session, and the page draws its own bat where the bridge predicts it.
//
// Frame: the engine's (x along the table, player A at x < 0, y across, z up, origin at the
// centre of the playing surface, metres); ITTF dimensions as in the engine's scenes.
import * as THREE from "./vendor/three.module.min.js";
import { Decoder } from "./decoder.js";

const TABLE_LENGTH = 2.74, TABLE_WIDTH = 1.525, TABLE_THICKNESS = 0.03, FLOOR_Z = -0.76;
const NET_HEIGHT = 0.1525, NET_OVERHANG = 0.1525, BALL_RADIUS = 0.02, BAT_RADIUS = 0.075;
const DELAY_S = 0.1;  // the spectator's view runs this far behind (join --delay-ms 100)
const BUFFER = 64;  // snapshots kept for interpolation
const BANNER_S = 2.5;
const NET_QUEUE = 256;  // net messages waiting for their tick (4 s of a 60 Hz two-message net)

const state = {
  frames: 0, snapshots: 0, events: 0, connected: false, ended: "", tick: -1, score: [0, 0],
  games: [0, 0], server: 0, phase: "", lastEvent: null, camera: "side", errors: [], nets: 0, netShown: 0,
  netTick: -1, netKnots: 0, ball: null,  // ball: [x, y, z] m, where the last frame drew it
  seat: "", predicted: 0, rejected: "", keysSent: 0, aimsSent: 0,
};
const KEYS = { w: "up", ArrowUp: "up", s: "down", ArrowDown: "down", a: "left", ArrowLeft: "left", d: "right",
               ArrowRight: "right", r: "raise", f: "lower", " ": "stroke" };
const AIM_EVERY_S = 1 / 30;
window.__pingpong = state;  // what the page shows, for its tests

function box(w, d, h, color, x, y, z) {
  const mesh = new THREE.Mesh(new THREE.BoxGeometry(w, d, h), new THREE.MeshStandardMaterial({ color }));
  mesh.position.set(x, y, z);
  return mesh;
}

function buildScene() {
  THREE.Object3D.DEFAULT_UP.set(0, 0, 1);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1a2230);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x334455, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.4);
  sun.position.set(-2, -3, 6);
  scene.add(sun);
  const floor = new THREE.Mesh(new THREE.PlaneGeometry(14, 9), new THREE.MeshStandardMaterial({ color: 0x7a4a32 }));
  floor.position.z = FLOOR_Z;
  scene.add(floor);
  scene.add(box(TABLE_LENGTH, TABLE_WIDTH, TABLE_THICKNESS, 0x1d4f8c, 0, 0, -TABLE_THICKNESS / 2));
  for (const sx of [-1, 1]) for (const sy of [-1, 1]) {  // legs
    const h = -FLOOR_Z - TABLE_THICKNESS;
    scene.add(box(0.05, 0.05, h, 0x222222, sx * (TABLE_LENGTH / 2 - 0.2), sy * (TABLE_WIDTH / 2 - 0.15), FLOOR_Z + h / 2));
  }
  const white = 0xffffff, lineZ = 0.0005;
  scene.add(box(TABLE_LENGTH, 0.02, 0.001, white, 0, TABLE_WIDTH / 2 - 0.01, lineZ));  // side lines
  scene.add(box(TABLE_LENGTH, 0.02, 0.001, white, 0, -TABLE_WIDTH / 2 + 0.01, lineZ));
  scene.add(box(0.02, TABLE_WIDTH, 0.001, white, TABLE_LENGTH / 2 - 0.01, 0, lineZ));  // end lines
  scene.add(box(0.02, TABLE_WIDTH, 0.001, white, -TABLE_LENGTH / 2 + 0.01, 0, lineZ));
  scene.add(box(TABLE_LENGTH, 0.003, 0.001, white, 0, 0, lineZ));  // centre line (doubles)
  const postY = TABLE_WIDTH / 2 + NET_OVERHANG;
  for (const sy of [-1, 1]) {
    const post = new THREE.Mesh(new THREE.CylinderGeometry(0.01, 0.01, NET_HEIGHT, 12),
                                new THREE.MeshStandardMaterial({ color: 0x333333 }));
    post.rotation.x = Math.PI / 2;  // a cylinder stands along y in three.js: turn it up z
    post.position.set(0, sy * postY, NET_HEIGHT / 2);
    scene.add(post);
  }
  const net = new THREE.Mesh(new THREE.PlaneGeometry(2 * postY, NET_HEIGHT),
                             new THREE.MeshStandardMaterial({ color: 0xeeeeee, transparent: true, opacity: 0.45,
                                                              side: THREE.DoubleSide }));
  net.quaternion.setFromRotationMatrix(new THREE.Matrix4().makeBasis(  // width along y, height up z
    new THREE.Vector3(0, 1, 0), new THREE.Vector3(0, 0, 1), new THREE.Vector3(1, 0, 0)));
  net.position.set(0, 0, NET_HEIGHT / 2);
  scene.add(net);  // the rigid net; hidden once a cloth net's knots come
  scene.add(box(0.004, 2 * postY, 0.012, white, 0, 0, NET_HEIGHT - 0.006));  // the net's white top band
  const bats = [0xc0392b, 0x27ae60].map((rim) => {
    const bat = new THREE.Group();
    const faces = [[0xd01818, 0.004], [0x111111, -0.004]];  // ITTF 2.4.6: one side red, the other black
    for (const [color, z] of faces) {
      const face = new THREE.Mesh(new THREE.CylinderGeometry(BAT_RADIUS, BAT_RADIUS, 0.004, 32),
                                  new THREE.MeshStandardMaterial({ color }));
      face.rotation.x = Math.PI / 2;  // the blade's normal is the bat's local z
      face.position.z = z;
      bat.add(face);
    }
    const blade = new THREE.Mesh(new THREE.CylinderGeometry(BAT_RADIUS + 0.002, BAT_RADIUS + 0.002, 0.004, 32),
                                 new THREE.MeshStandardMaterial({ color: rim }));
    blade.rotation.x = Math.PI / 2;
    bat.add(blade);
    bat.add(box(0.025, 0.1, 0.022, 0x8b5a2b, 0, -BAT_RADIUS - 0.045, 0));  // the handle
    scene.add(bat);
    return bat;
  });
  const ball = new THREE.Mesh(new THREE.SphereGeometry(BALL_RADIUS, 24, 16),
                              new THREE.MeshStandardMaterial({ color: 0xff9a1f, emissive: 0x331800 }));
  scene.add(ball);
  const shadow = new THREE.Mesh(new THREE.CircleGeometry(BALL_RADIUS, 24),
                                new THREE.MeshBasicMaterial({ color: 0x000000, transparent: true, opacity: 0.45 }));
  scene.add(shadow);
  return { scene, bats, ball, shadow, net };
}

// --- the cloth net: its knots (net messages) as the mesh's line segments ----------------------------
class Cloth {
  constructor(world, stepM) { this.world = world; this.stepM = stepM; this.lines = null; this.grid = ""; }

  build(m) {  // the mesh of a cols x rows grid: a segment to the right and one up from each knot
    const { cols, rows } = m;
    const index = [];
    for (let r = 0; r < rows; r++) for (let c = 0; c < cols; c++) {
      const k = r * cols + c;
      if (c + 1 < cols) index.push(k, k + 1);
      if (r + 1 < rows) index.push(k, k + cols);
    }
    const geometry = new THREE.BufferGeometry();
    this.pos = new Float32Array(cols * rows * 3);
    geometry.setAttribute("position", new THREE.BufferAttribute(this.pos, 3));
    geometry.setIndex(index);
    if (this.lines) { this.world.scene.remove(this.lines); this.lines.geometry.dispose(); }
    this.lines = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0xf2f2f2 }));
    this.lines.frustumCulled = false;  // its knots move: no stale bounding sphere
    this.world.scene.add(this.lines);
    this.world.net.visible = false;
    this.grid = `${cols}x${rows}x${m.width}x${m.height}`;
    state.netKnots = cols * rows;
  }

  take(m) {  // knot = rest (the grid in the plane x = 0) + offset * step, for knots first .. first + count
    if (this.grid !== `${m.cols}x${m.rows}x${m.width}x${m.height}`) this.build(m);
    const { cols, rows, width, height, first, count, offset } = m;
    for (let i = 0; i < count; i++) {
      const k = first + i, c = k % cols, r = Math.floor(k / cols);
      this.pos[3 * k] = offset[i][0] * this.stepM;
      this.pos[3 * k + 1] = -width / 2 + c * (width / (cols - 1)) + offset[i][1] * this.stepM;
      this.pos[3 * k + 2] = r * (height / (rows - 1)) + offset[i][2] * this.stepM;
    }
    this.lines.geometry.attributes.position.needsUpdate = true;
    state.netShown += 1;
    state.netTick = m.tick;
  }
}

// --- cameras ------------------------------------------------------------------------------------
function cameras(aspect) {
  const make = (x, y, z, tx, ty, tz) => {
    const camera = new THREE.PerspectiveCamera(45, aspect, 0.01, 100);
    camera.position.set(x, y, z);
    camera.lookAt(tx, ty, tz);
    return camera;
  };
  return {
    orbit: make(0, -4, 2.2, 0, 0, 0),
    side: make(-1.3, -4.1, 1.7, 0, 0, 0),  // broadcast: from the side, a little towards A, the net at an angle
    a: make(-TABLE_LENGTH / 2 - 1.6, 0, 0.75, 0.5, 0, 0),
    b: make(TABLE_LENGTH / 2 + 1.6, 0, 0.75, -0.5, 0, 0),
  };
}

class Orbit {  // drag: turn around the table; wheel: nearer or farther
  constructor(camera, element) {
    this.camera = camera;
    this.azimuth = -Math.PI / 2; this.elevation = 0.5; this.distance = 4.6;
    let dragging = null;
    element.addEventListener("pointerdown", (e) => { dragging = [e.clientX, e.clientY]; });
    window.addEventListener("pointerup", () => { dragging = null; });
    window.addEventListener("pointermove", (e) => {
      if (!dragging || state.camera !== "orbit") return;
      this.azimuth -= (e.clientX - dragging[0]) * 0.008;
      this.elevation = Math.min(1.45, Math.max(-0.1, this.elevation + (e.clientY - dragging[1]) * 0.006));
      dragging = [e.clientX, e.clientY];
      this.update();
    });
    element.addEventListener("wheel", (e) => {
      this.distance = Math.min(15, Math.max(1, this.distance * Math.exp(e.deltaY * 0.001)));
      this.update();
    }, { passive: true });
    this.update();
  }

  update() {
    const c = Math.cos(this.elevation);
    this.camera.position.set(this.distance * c * Math.cos(this.azimuth), this.distance * c * Math.sin(this.azimuth),
                             this.distance * Math.sin(this.elevation));
    this.camera.lookAt(0, 0, 0);
  }
}

// --- snapshots, interpolated ----------------------------------------------------------------------
class Timeline {
  constructor() { this.snapshots = []; this.offset = null; this.dt = 0.001; }

  push(snapshot, now) {  // now: s, the receiver's clock
    const t = snapshot.tick * this.dt;
    const offset = now - t;  // the least delayed snapshot sets the server clock's offset
    this.offset = this.offset === null ? offset : Math.min(this.offset + 0.0005, offset);
    const list = this.snapshots;
    if (list.length && snapshot.tick <= list[list.length - 1].tick) {
      if (snapshot.tick < list[list.length - 1].tick) list.length = 0;  // a new run: start again
      else return;
    }
    list.push(snapshot);
    if (list.length > BUFFER) list.shift();
  }

  sample(now) {  // the state DELAY_S behind the newest, interpolated; null before any snapshot
    const list = this.snapshots;
    if (!list.length) return null;
    const t = (now - this.offset - DELAY_S) / this.dt;
    if (t <= list[0].tick) return { a: list[0], b: list[0], f: 0 };
    for (let i = 1; i < list.length; i++) {
      if (list[i].tick >= t) {
        const a = list[i - 1], b = list[i];
        return { a, b, f: (t - a.tick) / (b.tick - a.tick) };
      }
    }
    const last = list[list.length - 1];
    return { a: last, b: last, f: 0 };
  }
}

const lerp = (p, q, f) => p.map((v, i) => v + (q[i] - v) * f);

function quatOf(wxyz) { return new THREE.Quaternion(wxyz[1], wxyz[2], wxyz[3], wxyz[0]); }

// --- the page -------------------------------------------------------------------------------------
function page(protocol, send) {
  const decoder = new Decoder(protocol);
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  document.body.prepend(renderer.domElement);
  const world = buildScene();
  const views = cameras(window.innerWidth / window.innerHeight);
  const orbit = new Orbit(views.orbit, renderer.domElement);
  const timeline = new Timeline();
  const cloth = new Cloth(world, protocol.net_step_m);
  const netQueue = [];  // net messages in arrival order, each shown once the view reaches its tick
  const $ = (id) => document.getElementById(id);
  let bannerUntil = 0;
  let predicted = null, predictedAt = 0, lastAim = 0;

  function resize() {
    renderer.setSize(window.innerWidth, window.innerHeight);
    for (const camera of Object.values(views)) {
      camera.aspect = window.innerWidth / window.innerHeight;
      camera.updateProjectionMatrix();
    }
  }
  window.addEventListener("resize", resize);
  resize();

  function choose(name) {
    state.camera = name;
    for (const button of document.querySelectorAll("#cameras button")) {
      button.classList.toggle("on", button.dataset.camera === name);
    }
    if (name === "orbit") orbit.update();
  }
  for (const button of document.querySelectorAll("#cameras button")) {
    button.addEventListener("click", () => choose(button.dataset.camera));
  }
  window.addEventListener("keydown", (e) => {
    const name = { 1: "orbit", 2: "side", 3: "a", 4: "b" }[e.key];
    if (name) choose(name);
    const key = KEYS[e.key.length === 1 ? e.key.toLowerCase() : e.key];
    if (key && state.seat && send) {
      send({ key });
      state.keysSent += 1;
      e.preventDefault();
    }
  });
  for (const button of document.querySelectorAll("#play button")) {
    button.addEventListener("click", () => { if (send && !state.seat) send({ play: button.dataset.seat }); });
    if (!send) button.style.display = "none";  // a replay plays nothing
  }
  const ray = new THREE.Raycaster(), pointer = new THREE.Vector2(), hit = new THREE.Vector3();
  renderer.domElement.addEventListener("pointermove", (e) => {  // the bat follows the pointer on a plane
    const now = performance.now() / 1000;  // in front of the player: its end line, 30 cm out
    if (!state.seat || !send || e.buttons || now - lastAim < AIM_EVERY_S) return;
    const sign = state.seat === "a" ? -1 : 1;
    pointer.set((e.clientX / window.innerWidth) * 2 - 1, -(e.clientY / window.innerHeight) * 2 + 1);
    ray.setFromCamera(pointer, views[state.camera]);
    const plane = new THREE.Plane(new THREE.Vector3(1, 0, 0), -sign * (TABLE_LENGTH / 2 + 0.3));
    if (ray.ray.intersectPlane(plane, hit)) {
      send({ aim: [hit.x, hit.y, hit.z] });
      state.aimsSent += 1;
      lastAim = now;
    }
  });
  choose(state.camera);

  function banner(text) {
    $("banner").textContent = text;
    bannerUntil = performance.now() / 1000 + BANNER_S;
  }

  function showScore(s) {
    state.score = s.score.slice(); state.games = s.games_won.slice(); state.server = s.server;
    state.phase = decoder.name("Phase", s.phase);
    $("points-a").textContent = s.score[0]; $("points-b").textContent = s.score[1];
    $("games-a").textContent = s.games_won[0]; $("games-b").textContent = s.games_won[1];
    $("serve-a").textContent = s.server === 0 ? "●" : ""; $("serve-b").textContent = s.server === 1 ? "●" : "";
  }

  function take(data, now) {
    const message = decoder.decode(data);
    if (message.kind === "welcome") {
      timeline.dt = message.dt;
      $("name-a").textContent = message.name_a || "A";
      $("name-b").textContent = message.name_b || "B";
      $("status").textContent = `${message.scene}, best of ${message.best_of}`;
    } else if (message.kind === "snapshot") {
      state.snapshots += 1;
      timeline.push(message, now);
    } else if (message.kind === "net") {
      state.nets += 1;
      netQueue.push(message);
      if (netQueue.length > NET_QUEUE) cloth.take(netQueue.shift());  // a view that fell behind
    } else if (message.kind === "event") {
      state.events += 1;
      state.lastEvent = { event: decoder.name("EventKind", message.event), winner: message.winner,
                          reason: decoder.name("Reason", message.reason), score: message.score };
      const who = message.winner < 0 ? "let" : `point ${"AB"[message.winner]}`;
      const what = { point: "", game: " - game", match: " - match" }[state.lastEvent.event];
      banner(`${who}: ${state.lastEvent.reason.replaceAll("_", " ")}${what}`);
    } else if (message.kind === "goodbye") {
      state.ended = decoder.name("GoodbyeReason", message.reason);
      $("status").textContent = `ended: ${state.ended.replaceAll("_", " ")}`;
    }
    return message;
  }

  function takeText(reply) {  // the bridge's answers to a browser that plays
    if (reply.seat) {
      state.seat = reply.seat;
      document.body.classList.add("playing");
      $("status").textContent = `you play ${reply.seat.toUpperCase()}`;
      choose(reply.seat);
    } else if (reply.predicted) {
      predicted = reply.predicted;
      predictedAt = performance.now() / 1000;
      state.predicted += 1;
    } else if (reply.rejected) {
      state.rejected = reply.rejected;
      $("status").textContent = `no seat: ${reply.rejected.replaceAll("_", " ")}`;
    } else if (reply.ended) {
      state.seat = "";
      document.body.classList.remove("playing");
    }
  }

  function draw() {
    const now = performance.now() / 1000;
    const sample = timeline.sample(now);
    if (sample) {
      const { a, b, f } = sample;
      world.ball.position.fromArray(lerp(a.ball_pos, b.ball_pos, f));
      for (let i = 0; i < 2; i++) {
        world.bats[i].position.fromArray(lerp(a.bat_pos[i], b.bat_pos[i], f));
        world.bats[i].quaternion.copy(quatOf(a.bat_quat[i]).slerp(quatOf(b.bat_quat[i]), f));
      }
      if (state.seat && predicted && performance.now() / 1000 - predictedAt < 0.25) {  // our bat, predicted
        const own = world.bats[state.seat === "a" ? 0 : 1];
        own.position.fromArray(predicted.bat_pos);
        own.quaternion.copy(quatOf(predicted.bat_quat));
      }
      const p = world.ball.position;
      state.ball = [p.x, p.y, p.z];
      const onTable = Math.abs(p.x) <= TABLE_LENGTH / 2 && Math.abs(p.y) <= TABLE_WIDTH / 2 && p.z > -0.01;
      world.shadow.position.set(p.x, p.y, onTable ? 0.001 : FLOOR_Z + 0.001);
      const shown = f < 0.5 ? a : b;
      state.tick = shown.tick;
      showScore(shown);
    }
    const viewTick = sample ? sample.a.tick + (sample.b.tick - sample.a.tick) * sample.f : Infinity;
    while (netQueue.length && netQueue[0].tick <= viewTick) cloth.take(netQueue.shift());
    if (now > bannerUntil) $("banner").textContent = state.ended === "match_over" ? "match over" : "";
    renderer.render(world.scene, views[state.camera]);
    state.frames += 1;
    requestAnimationFrame(draw);
  }
  requestAnimationFrame(draw);
  return { take, takeText };
}

window.addEventListener("error", (e) => state.errors.push(String(e.message)));

/** The live page: the bridge's /protocol.json, then its WebSocket /ws. */
export async function startLive() {
  const protocol = await (await fetch("protocol.json")).json();
  const socket = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
  const view = page(protocol, (request) => {
    if (socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(request));
  });
  socket.binaryType = "arraybuffer";
  socket.addEventListener("open", () => { state.connected = true; });
  socket.addEventListener("close", () => {
    state.connected = false;
    if (!state.ended) document.getElementById("status").textContent = "disconnected";
  });
  socket.addEventListener("message", (e) => {
    if (typeof e.data === "string") view.takeText(JSON.parse(e.data));
    else view.take(e.data, performance.now() / 1000);
  });
}

/** A recorded match, offline: `messages` are wire messages (base64), played at their ticks. */
export function startReplay(protocol, messages) {
  const view = page(protocol, null);
  const bytes = messages.map((text) => Uint8Array.from(atob(text), (c) => c.charCodeAt(0)));
  state.connected = true;
  let dt = 0.001, start = null, next = 0;
  function feed() {
    const now = performance.now() / 1000;
    while (next < bytes.length) {
      const data = bytes[next];
      if (data[6] !== 2) {  // every message but the welcome plays at its tick's time
        const tick = Number(new DataView(data.buffer, data.byteOffset).getBigInt64(16, true));
        if (start === null) start = now - tick * dt;
        if (tick * dt > now - start) break;
      }
      const message = view.take(data, now);
      if (message.kind === "welcome") dt = message.dt;
      next += 1;
    }
    if (next < bytes.length) requestAnimationFrame(feed);
    else state.ended = state.ended || "replay_over";
  }
  requestAnimationFrame(feed);
}
