// Sculpt's browser client: join a scene over sculptd's WebSocket as a viewer or a sculptor, see
// the shared sculpture from its Draco chunks, sculpt with the pointer, see who else is there.
// Modules: connection.js (the wire), meshes.js (mesh assembly), packing.js (stroke poses),
// tools.js (pointer sculpting, painting and presence), contours.js (skin and slice panels, over
// contour_codec.js), undo.js (undo and redo); this file is the page and its state.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { Connection, Outbox, clusterHttpAddresses, describeError, kDeclaredResendSeconds, num, v1 } from './connection.js';
import { ChunkMeshes } from './meshes.js';
import { Sculpting, Presence, isUnavailable } from './tools.js';
import { Contours } from './contours.js';
import { UndoControls } from './undo.js';

const $ = (id) => document.getElementById(id);
const kBusyChunks = 16;    // chunks in the decoder above which frames are spaced out
const kBusyFrameMs = 500;
// Redirects followed in a row for one join before giving up (members that disagree about a
// scene's owner, or a forged answer, must not bounce the page around for ever).
const kMaxRedirects = 3;
// Reconnection after the connection is lost or a cluster member refuses an edit because it does
// not hold the scene now (a failover: the owner's lease lapsed, the standby takes over in about
// the lease TTL plus its restart): tries, each through every known member, after a growing pause.
const kReconnectTries = 12;
const kReconnectFirstMs = 250;
const kReconnectMaxMs = 4000;
// The pace of the edits the page sends, resends after a reconnection included, as a share of
// the server's per-client token buckets (its defaults: 240 strokes/s with a burst of 60, 960
// poses/s with a burst of 480; Welcome names the stroke rate, server_config.h the others).
const kRateShare = 0.75;
const kServerPosesPerSecond = 960;
const kServerPoseBurst = 480;
const kServerStrokeBurst = 60;

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/**
 * Reads #token=...&role=...&name=...&scene=...&members=HOST:PORT,... (the fragment never reaches
 * a server); `members`: other cluster members' HTTP addresses to rejoin through when the one that
 * served the page is gone too.
 */
function fragmentOptions() {
  const params = new URLSearchParams(location.hash.replace(/^#/, ''));
  return { token: params.get('token'), role: params.get('role'), name: params.get('name'),
    scene: params.get('scene') || '',
    members: (params.get('members') || '').split(',').map((m) => m.trim()).filter(Boolean) };
}

function percentile(sorted, q) {
  if (sorted.length === 0) return 0;
  return sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
}

class App {
  constructor() {
    this.stats = { state: 'idle', role: '', globalSeq: 0, acks: 0, strokesSent: 0, paintsSent: 0, paintsAcked: 0,
      errors: [], ackLatencies: [], chunksPerSecond: 0, bytesPerSecond: 0, presence: [] };
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(2, window.devicePixelRatio || 1));
    $('view').appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x2a2f37);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 5000);
    this.camera.position.set(30, 20, 40);
    this.scene.add(new THREE.HemisphereLight(0xf4f1ea, 0x3a3530, 1.4));
    const sun = new THREE.DirectionalLight(0xffffff, 1.8);
    sun.position.set(1, 2, 1.5);
    this.camera.add(sun);
    this.scene.add(this.camera);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = true;
    this.meshes = new ChunkMeshes(this.scene);
    this.meshes.onChange = () => {
      if (!this.framed && this.meshes.chunks.size > 0) this.frameSoon();
      this.invalidate();
    };
    this.presence = new Presence(this.scene, $('people-list'));
    this.skinEditSeq = 0;
    this.pendingSkinEdits = new Map();  // ball edit client_seq -> its skin panel
    this.framed = false;
    this.frameTimes = [];  // ms per drawn frame, newest last
    this.lastFrameAt = 0;
    window.addEventListener('resize', () => this.resize());
    this.resize();
    // Drawn on demand (a change of view, mesh, tool or presence), not 60 times a second: a
    // software-rendered browser (no GPU) would otherwise spend a core on unchanged frames.
    this.controls.addEventListener('change', () => this.invalidate());
    this.lastRate = { t: performance.now(), bytes: 0, chunks: 0 };
    setInterval(() => this.updateRates(), 1000);
    setInterval(() => this.showStatus(), 250);
  }

  resize() {
    const el = $('view');
    const w = el.clientWidth || window.innerWidth, h = el.clientHeight || window.innerHeight;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / Math.max(1, h);
    this.camera.updateProjectionMatrix();
    this.invalidate();
  }

  invalidate() {
    if (this.frameRequested) return;
    this.frameRequested = true;
    // While a large batch of chunks is being decoded (a late join, a big update), a frame every
    // kBusyFrameMs is enough: with software WebGL each frame of a large object costs the CPU
    // the decoding needs, and drawing every partial state made the first full mesh later.
    const busy = this.meshes.decoding > kBusyChunks;
    const wait = busy ? this.lastFrameAt + kBusyFrameMs - performance.now() : 0;
    if (wait > 0) setTimeout(() => requestAnimationFrame(() => this.frame()), wait);
    else requestAnimationFrame(() => this.frame());
  }

  frame() {
    this.frameRequested = false;
    this.frameStarted = performance.now();
    this.lastFrameAt = this.frameStarted;
    // Damping keeps the view moving after the pointer stops: update() reports it changed.
    if (this.controls.update()) this.invalidate();
    if (this.continuous) this.invalidate();  // a benchmark's frame-rate measurement
    this.renderer.render(this.scene, this.camera);
    this.stats.frameMs = performance.now() - this.frameStarted;
    this.frameTimes.push(this.stats.frameMs);
    if (this.frameTimes.length > 20000) this.frameTimes.shift();
    this.stats.frames = (this.stats.frames || 0) + 1;
  }

  frameSoon() {
    clearTimeout(this.frameTimer);
    this.frameTimer = setTimeout(() => this.frameObject(), 150);
  }

  /** Points the camera at the whole object. */
  frameObject() {
    const box = this.meshes.bounds();
    if (box.isEmpty()) return;
    this.framed = true;
    const centre = box.getCenter(new THREE.Vector3());
    const radius = box.getSize(new THREE.Vector3()).length() / 2;
    const dist = radius / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2)) * 1.1;
    const dir = new THREE.Vector3(0.55, 0.4, 0.75).normalize();
    this.camera.position.copy(centre).addScaledVector(dir, dist);
    this.camera.near = dist / 100;
    this.camera.far = dist * 10;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(centre);
    this.controls.update();
    this.invalidate();
  }

  showError(text) {
    this.stats.errors.push(text);
    const div = document.createElement('div');
    div.className = 'error';
    div.textContent = text;
    $('errors').appendChild(div);
    while ($('errors').children.length > 4) $('errors').firstChild.remove();
    console.warn(`sculpt: ${text}`);
  }

  updateRates() {
    const now = performance.now();
    const dt = (now - this.lastRate.t) / 1000;
    const bytes = this.conn ? this.conn.bytesIn : 0;
    this.stats.bytesPerSecond = (bytes - this.lastRate.bytes) / dt;
    this.stats.chunksPerSecond = (this.meshes.received - this.lastRate.chunks) / dt;
    this.lastRate = { t: now, bytes, chunks: this.meshes.received };
  }

  showStatus() {
    const s = this.stats;
    const lat = [...s.ackLatencies].sort((a, b) => a - b);
    const t = this.meshes.totals();
    $('status').textContent = [
      s.state, s.role || '-', `seq ${s.globalSeq}`,
      // A viewer sends no strokes, and a sculptor has no latency before its first ack: say so
      // rather than show a latency of 0 ms.
      s.role === 'viewer' ? 'no strokes (viewer)'
        : lat.length === 0 ? 'no acks yet'
          : `ack p50 ${percentile(lat, 0.5).toFixed(1)} ms p99 ${percentile(lat, 0.99).toFixed(1)} ms`,
      `${(s.bytesPerSecond / 1024).toFixed(1)} KB/s`, `${s.chunksPerSecond.toFixed(1)} chunks/s`,
      `${t.chunks} chunks ${t.faces} triangles`,
    ].join('  |  ');
  }

  /** A short line above the status bar ("scene is on member a, reconnecting"); '' hides it. */
  showNotice(text) {
    this.stats.notice = text;
    $('notice').textContent = text;
    $('notice').hidden = !text;
    if (text) console.info(`sculpt: ${text}`);
  }

  /**
   * Opens /ws on `host`, says Hello and sends JoinScene: { redirect } when this member does
   * not own the scene (cluster mode, proto/README.md "Redirects"), else { welcome, info }.
   */
  async connectAndJoin(host, { token, role, name, scene }, clientId) {
    const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
    const conn = this.conn;
    if (!this.reconnecting) this.stats.state = 'connecting';
    this.stats.server = host;
    await conn.open(`${proto}//${host}/ws`);
    const wantRole = role === 'viewer' ? v1.Role.ROLE_VIEWER : v1.Role.ROLE_SCULPTOR;
    conn.send('hello', { protocolVersion: 1, token: token || '', role: wantRole,
      clientName: (name || 'browser').slice(0, 64), clientId });
    const welcome = await conn.next('welcome');
    // After a reconnection, the unanswered edits about to be resent (Outbox.resendRanges).
    const resends = this.outbox
      ? this.outbox.resendRanges(Math.floor(kDeclaredResendSeconds * (welcome.maxStrokesPerSecond || 0)))
      : [];
    conn.send('join', { scene, skipState: true, resends });
    const answer = await conn.nextOf(['sceneInfo', 'redirect']);
    if (answer.type === 'redirect') {
      // The Bye that follows is not an error to show: this socket is closed and forgotten.
      conn.close('redirected');
      return { redirect: answer.detail };
    }
    return { welcome, info: answer.detail };
  }

  /** The page's one Connection and the listeners that outlive its sockets. */
  makeConnection() {
    const conn = new Connection();
    this.conn = conn;
    const joined = () => ['joined', 'resending'].includes(this.stats.state);
    conn.addEventListener('close', (ev) => {
      if (!joined()) return;
      const reason = this.lastBye || ev.detail.reason;
      this.reconnect(`connection to ${this.stats.server} closed${reason ? ` (${reason})` : ''}`);
    });
    conn.addEventListener('error', (ev) => {
      const e = ev.detail;
      // A member that does not hold the scene now (its lease lapsed, a failover): the edit and
      // every later one are resent through a new connection (proto/README.md, cluster mode).
      if (isUnavailable(e) && num(e.clientSeq) !== 0 && joined()) {
        this.reconnect(describeError(e));
        return;
      }
      // While reconnecting, a member's refusal of a join is said in the notice (the next member
      // or try may do); paint and undo refusals are also said as an Error with client_seq 0.
      if (this.reconnecting || (isUnavailable(e) && joined())) {
        console.info(`sculpt: ${describeError(e)}`);
        return;
      }
      this.showError(describeError(e));
    });
    conn.addEventListener('bye', (ev) => {
      // Said in the reconnection notice when the socket then closes.
      if (joined() && ev.detail.reason) this.lastBye = ev.detail.reason;
    });
    conn.addEventListener('protocol-error', (ev) => this.showError(`bad message: ${ev.detail}`));
    for (const type of ['paintAck', 'undoAck']) {
      conn.addEventListener(type, (ev) => {
        if (!ev.detail.accepted && isUnavailable(ev.detail.error) && joined()) {
          this.reconnect(describeError(ev.detail.error));
        }
      });
    }
    conn.addEventListener('meshChunk', (ev) => {
      this.stats.globalSeq = Math.max(this.stats.globalSeq, num(ev.detail.version));
      this.meshes.add(ev.detail);
    });
    conn.addEventListener('presence', (ev) => {
      this.presence.update(ev.detail);
      this.stats.presence = this.presence.others();
      this.invalidate();
    });
    return conn;
  }

  /**
   * Joins the scene through `host`, following redirects (at most kMaxRedirects in a row), with
   * `clientId`: { welcome, info, host } of the member that serves it.
   */
  async joinFollowingRedirects(host, opts, clientId) {
    let joined;
    this.stats.redirects = 0;
    this.stats.member = '';  // the owner's member name, when a redirect said it
    for (;;) {
      try {
        joined = await this.connectAndJoin(host, opts, clientId);
      } catch (err) {
        // A socket to another member is cross-origin: refused unless each member lists the
        // others' page origins (docs/cluster.md, "Browser and operator").
        if (this.stats.redirects > 0 && !err.wire && host !== location.host) {
          err.message += ` (redirected to member ${this.stats.member}: its --http-allow-origin must list `
            + `${location.origin}, and this member's must list ${location.protocol}//${host})`;
        }
        throw err;
      }
      const r = joined.redirect;
      if (!r) break;
      const where = `member ${r.member || '?'}${r.httpAddress ? ` at ${r.httpAddress}` : ''}`;
      const scene = r.scene || opts.scene || 'default';
      if (this.stats.redirects >= kMaxRedirects) {
        throw new Error(`scene "${scene}" was redirected ${this.stats.redirects + 1} times in a row `
          + `(last to ${where}, epoch ${num(r.epoch)}): the members disagree about its owner; try again later`);
      }
      if (!r.httpAddress) {
        throw new Error(`scene "${scene}" is on ${where}, which has no HTTP port for the browser`);
      }
      this.stats.redirects += 1;
      this.stats.member = r.member;
      if (this.stats.state !== 'reconnecting') this.showNotice(`scene "${scene}" is on ${where}, reconnecting`);
      else console.info(`sculpt: scene "${scene}" is on ${where}, reconnecting`);
      host = r.httpAddress;
    }
    return { ...joined, host };
  }

  async join(opts) {
    // One client id for the page, redirects and reconnections included: the owner sees the same
    // client, so it recognises a resent edit it already applied.
    const clientId = Math.floor(Math.random() * 2 ** 48) + 1;
    this.clientId = clientId;
    this.opts = opts;
    if (!this.conn) this.makeConnection();
    const { welcome, info, host } = await this.joinFollowingRedirects(location.host, opts, clientId);
    if (this.stats.redirects > 0) {
      this.showNotice(`scene "${info.scene}" is on member ${this.stats.member} (${host})`);
    }
    this.joinedHost = host;
    this.learnMembers(info);
    this.welcome = welcome;
    this.stats.role = welcome.role === v1.Role.ROLE_VIEWER ? 'viewer' : 'sculptor';
    this.info = info;
    this.stats.scene = info.scene;
    const strokesPerSecond = kRateShare * (welcome.maxStrokesPerSecond || 240);
    this.outbox = new Outbox((body, value) => this.conn.send(body, value), {
      strokesPerSecond, strokeBurst: Math.max(1, Math.floor(kRateShare * kServerStrokeBurst)),
      posesPerSecond: kRateShare * kServerPosesPerSecond, poseBurst: Math.floor(kRateShare * kServerPoseBurst) });
    // The resend after a reconnection is done when no request is left unanswered.
    this.outbox.onEmpty = () => this.checkResendDone();
    this.stats.reconnects = 0;
    this.stats.resent = 0;
    this.joined(welcome, info);
    // Skin contours and slices, when the scene computes them.
    if (info.effects && info.effects.contours) this.contours = new Contours(this, info, this.stats.role === 'sculptor');
    if (this.stats.role === 'sculptor') {
      this.sculpting = new Sculpting(this, info, welcome, clientId);
      this.undo = new UndoControls(this, this.sculpting, welcome);
      $('tools').hidden = false;
      // The left button and one finger sculpt; the view moves with the others (the wheel zooms).
      this.controls.mouseButtons = { LEFT: -1, MIDDLE: THREE.MOUSE.PAN, RIGHT: THREE.MOUSE.ROTATE };
      this.controls.touches = { ONE: -1, TWO: THREE.TOUCH.DOLLY_ROTATE };
    }
    this.outbox.resume();
    document.title = `Sculpt: ${info.scene} (${this.stats.role})`;
  }

  /** What every join, first or again, sets up on its new connection. */
  joined(welcome, info) {
    this.presence.ownSession = num(welcome.sessionId);
    this.stats.state = 'joined';
    this.stats.globalSeq = Math.max(this.stats.globalSeq, num(info.globalSeq));
    for (const o of info.objects) this.conn.send('viewerSubscribe', { object: o.name, maxRateHz: 10 });
  }

  /**
   * Cluster mode: the members' HTTP addresses the SceneInfo of a join listed (valid HOST:PORT,
   * distinct, at most 64), kept for rejoining when the members the page knew otherwise are gone.
   * A SceneInfo without members (a single process, or a member that has not read them yet)
   * keeps the list from before.
   */
  learnMembers(info) {
    const learnt = clusterHttpAddresses(info);
    if (learnt.length > 0) this.learntMembers = learnt;
    this.stats.learntMembers = this.learntMembers || [];
  }

  /**
   * The connection is lost, or its member refused an edit because it does not hold the scene
   * now: rejoins through the members the page knows (the last one it joined, the one that served
   * the page, the fragment's `members`, then the members the last join's SceneInfo listed), each join following redirects to the scene's owner, with
   * a growing pause between tries, then resends every unacknowledged edit in order (Outbox). New
   * edits made meanwhile wait in the outbox and follow the resent ones.
   */
  async reconnect(why) {
    if (this.reconnecting) return;
    this.reconnecting = true;
    try {
      return await this.rejoin(why);
    } finally {
      this.reconnecting = false;
      this.lastBye = '';
    }
  }

  async rejoin(why) {
    this.outbox.hold();
    this.conn.close('reconnecting');  // nothing more to a member that may not acknowledge
    this.stats.state = 'reconnecting';
    this.stats.reconnects += 1;
    this.stats.lastLoss = why;
    const started = performance.now();
    const hosts = [...new Set([this.joinedHost, location.host, ...(this.opts.members || []),
      ...(this.learntMembers || [])])];
    let last = why;
    for (let attempt = 1; attempt <= kReconnectTries; ++attempt) {
      // Short: the line sits over the view. Why is said in the console (and if all tries fail).
      const waiting = this.outbox.size;
      this.showNotice(`reconnecting… (try ${attempt} of ${kReconnectTries}, ${waiting} edit${waiting === 1 ? '' : 's'} kept)`);
      console.info(`sculpt: ${last}`);
      await sleep(Math.min(kReconnectMaxMs, kReconnectFirstMs * 2 ** (attempt - 1)) * (0.75 + 0.5 * Math.random()));
      for (const host of hosts) {
        let joined;
        try {
          joined = await this.joinFollowingRedirects(host, this.opts, this.clientId);
        } catch (err) {
          last = `${host}: ${err.message}`;
          // A refused token or role will be refused on every member: no point trying on.
          const code = err.wire && err.wire.code;
          if (code === v1.ErrorCode.ERROR_CODE_UNAUTHENTICATED || code === v1.ErrorCode.ERROR_CODE_PERMISSION_DENIED) {
            return this.giveUp(last);
          }
          continue;
        }
        this.joinedHost = joined.host;
        this.learnMembers(joined.info);
        this.welcome = joined.welcome;
        this.info = joined.info;
        this.joined(joined.welcome, joined.info);
        this.resubscribeContours();
        const resent = this.outbox.resume();
        this.stats.resent += resent;
        this.stats.lastReconnectMs = performance.now() - started;
        this.resend = { resent, member: this.stats.member || '', host: joined.host };
        this.stats.state = 'resending';
        this.showNotice(`reconnected to ${this.where(joined.host)}; resending ${resent} unacknowledged `
          + `edit${resent === 1 ? '' : 's'}`);
        this.checkResendDone();
        return undefined;
      }
    }
    return this.giveUp(last);
  }

  /** "member b (127.0.0.1:8081)", or the address alone outside a cluster. */
  where(host) {
    return this.stats.member ? `member ${this.stats.member} (${host})` : host;
  }

  /** After a reconnection: once the resent edits are all answered, says so. */
  checkResendDone() {
    if (this.stats.state !== 'resending' || !this.resend || this.outbox.size > 0) return;
    this.stats.state = 'joined';
    const n = this.resend.resent;
    this.showNotice(`reconnected to ${this.where(this.resend.host)}, resent ${n} stroke${n === 1 ? '' : 's'}`
      + ' (all acknowledged)');
  }

  giveUp(last) {
    this.stats.state = 'disconnected';
    this.showNotice('');
    const n = this.outbox.size;
    this.showError(`could not reconnect to scene "${this.stats.scene}" after ${kReconnectTries} tries (last: ${last}); `
      + `${n} edit${n === 1 ? ' was' : 's were'} not acknowledged: reload the page to join again`);
  }

  /** A new connection has no contour subscriptions: the panels' are made again. */
  resubscribeContours() {
    if (!this.contours) return;
    for (const name of this.contours.skins.keys()) this.conn.send('contourSubscribe', { skin: name });
    const slice = this.contours.slice;
    if (slice && slice.current) this.conn.send('contourSubscribe', { slice: slice.current });
  }
}

const app = new App();
window.sculpt = app;  // for the browser tests and the console
$('frame').addEventListener('click', () => app.frameObject());

async function start(opts) {
  $('join').hidden = true;
  try {
    await app.join(opts);
  } catch (err) {
    app.stats.state = 'refused';
    app.showNotice('');
    if (!err.wire) app.showError(err.message);  // a wire Error is already shown
    $('join').hidden = false;
  }
}

$('join').addEventListener('submit', (ev) => {
  ev.preventDefault();
  start({ token: $('join-token').value, role: $('join-role').value, name: $('join-name').value,
    scene: fragmentOptions().scene, members: fragmentOptions().members });
});

const frag = fragmentOptions();
if (frag.token) {
  $('join-token').value = frag.token;
  if (frag.role) $('join-role').value = frag.role;
  if (frag.name) $('join-name').value = frag.name;
  start({ token: frag.token, role: frag.role || 'sculptor', name: frag.name || 'browser', scene: frag.scene,
    members: frag.members });
}
