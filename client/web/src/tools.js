// Pointer sculpting and presence. A drag on the surface samples the pointer at its own rate;
// samples are sent as strokes at most 60 times a second (packed poses, packing.js) and drawn at
// once as a trail, which the server's chunks then replace. Hovering sends the tool's position
// for presence at 10 Hz; other sculptors' tools are drawn as translucent spheres in their colour.
import * as THREE from 'three';
import { num, v1 } from './connection.js';
import { packPoses, posesThatFit } from './packing.js';

const $ = (id) => document.getElementById(id);
const kStrokeHz = 60;

/** An Error (or an ack's error) that says the member does not hold the scene now. */
export function isUnavailable(e) {
  return !!e && e.code === v1.ErrorCode.ERROR_CODE_UNAVAILABLE;
}
const kHoverHz = 10;

export class Sculpting {
  constructor(app, info, welcome, clientId) {
    this.app = app;
    this.info = info;
    this.object = info.objects[0];
    this.voxelSize = this.object.voxelSize;
    this.maxPoses = Math.max(1, Math.min(welcome.maxPosesPerStroke || 32, 32));
    // A stroke's kernel work is bounded by the server (large tools: fewer poses a stroke).
    this.workLimits = {
      voxelSize: this.voxelSize,
      halfWidth: this.object.halfWidth || 3,
      shellRadii: (info.editSettings && info.editSettings.shellRadii) || 1,
      maxWork: num(welcome.maxStrokeWork || 0),
    };
    this.clientId = clientId;
    // One numbering for strokes, paints and undos: the server keeps a sequence per kind, so the
    // gaps are harmless, and an Error's client_seq names exactly one request of this page.
    this.seq = 0;
    this.pending = new Map();  // stroke client_seq -> send time
    // One drag is sent as several strokes (kStrokeHz); undo.js takes a drag back as a whole.
    this.gesture = 0;
    this.gestureOf = new Map();  // client_seq of a stroke not yet acked -> its drag
    this.samples = [];
    this.dragging = false;
    this.lastHover = 0;
    this.raycaster = new THREE.Raycaster();
    this.preview = new THREE.Mesh(new THREE.SphereGeometry(1, 24, 16),
      new THREE.MeshBasicMaterial({ color: 0x7fd0ff, transparent: true, opacity: 0.25, depthWrite: false }));
    this.preview.visible = false;
    app.scene.add(this.preview);
    this.trail = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xffe080 }));
    this.trailPoints = [];
    app.scene.add(this.trail);
    const el = app.renderer.domElement;
    el.addEventListener('pointerdown', (e) => this.down(e));
    el.addEventListener('pointermove', (e) => this.move(e));
    el.addEventListener('pointerup', (e) => this.up(e));
    el.addEventListener('pointercancel', (e) => this.up(e));
    el.addEventListener('contextmenu', (e) => e.preventDefault());
    app.conn.addEventListener('ack', (ev) => this.onAck(ev.detail));
    app.conn.addEventListener('paintAck', (ev) => this.onPaintAck(ev.detail));
    app.conn.addEventListener('error', (ev) => this.onError(ev.detail));
    this.pendingPaints = new Map();  // paint client_seq -> send time
    this.offerPaint(info.effects);
    this.timer = setInterval(() => this.flush(), 1000 / kStrokeHz);
  }

  /** The paint tool, with the scene's materials, when the scene declares any. */
  offerPaint(effects) {
    const materials = (effects && effects.materials) || [];
    if (materials.length === 0) return;
    const opt = document.createElement('option');
    opt.value = 'paint';
    opt.textContent = 'paint';
    $('tool-kind').appendChild(opt);
    const select = $('tool-material');
    materials.forEach((name, i) => {
      const o = document.createElement('option');
      o.value = String(i);
      o.textContent = name;
      select.appendChild(o);
    });
    const show = () => { $('material-label').hidden = $('tool-kind').value !== 'paint'; };
    $('tool-kind').addEventListener('change', show);
    show();
  }

  radius() {
    const r = Number($('tool-radius').value) * this.voxelSize * 2;
    return Math.min(this.info.maxToolSize || r, Math.max(this.info.minToolSize || r, r));
  }

  hit(e) {
    const rect = this.app.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1,
      -((e.clientY - rect.top) / rect.height) * 2 + 1);
    this.raycaster.setFromCamera(ndc, this.app.camera);
    const hits = this.raycaster.intersectObjects(this.app.meshes.meshes(), false);
    return hits.length ? hits[0].point : null;
  }

  down(e) {
    if (e.button !== 0) return;
    const p = this.hit(e);
    if (!p) return;
    this.dragging = true;
    this.gesture += 1;
    this.pressure = e.pressure > 0 ? e.pressure : 0.5;
    this.app.renderer.domElement.setPointerCapture(e.pointerId);
    this.sample(p);
  }

  move(e) {
    const p = this.hit(e);
    const r = this.radius();
    if (this.preview.visible !== !!p) this.app.invalidate();
    this.preview.visible = !!p;
    if (p) {
      this.app.invalidate();
      this.preview.position.copy(p);
      this.preview.scale.setScalar(r);
      const now = performance.now();
      if (now - this.lastHover > 1000 / kHoverHz) {
        this.lastHover = now;
        this.app.conn.send('hover', { position: { x: p.x, y: p.y, z: p.z }, radius: r });
      }
    }
    if (!this.dragging || !p) return;
    if (e.pressure > 0) this.pressure = e.pressure;
    const events = typeof e.getCoalescedEvents === 'function' ? e.getCoalescedEvents() : [];
    if (events.length > 1) {
      for (const c of events) { const q = this.hit(c); if (q) this.sample(q); }
    } else {
      this.sample(p);
    }
  }

  up(e) {
    if (!this.dragging) return;
    this.dragging = false;
    this.flush();
  }

  sample(p) {
    this.samples.push({ x: p.x, y: p.y, z: p.z, t: performance.now() });
    this.trailPoints.push(p.clone());
    this.trail.geometry.setFromPoints(this.trailPoints);
    this.app.invalidate();
    if (this.samples.length >= this.maxPoses) this.flush();
  }

  /** Sends the samples gathered since the last stroke as strokes (or one paint): as many poses
   *  a stroke as the server's limits allow for this tool. */
  flush() {
    if (this.samples.length === 0) return;
    if ($('tool-kind').value === 'paint') return this.flushPaint();
    const r = this.radius();
    while (this.samples.length > 0) {
      const fit = posesThatFit(this.samples.slice(0, this.maxPoses), r, this.workLimits);
      this.sendStroke(this.samples.splice(0, fit), r);
    }
  }

  sendStroke(poses, r) {
    const packed = packPoses(poses, this.voxelSize);
    if (!packed) { this.app.showError('stroke out of reach of its origin: dropped'); return; }
    const kind = Number($('tool-kind').value);
    const strength = Number($('tool-strength').value) * Math.min(1, 2 * this.pressure);
    const maxSpeed = this.info.maxSpeed || 10;
    const stroke = {
      clientSeq: ++this.seq,
      object: this.object.name,
      kind,
      tool: v1.ToolKind.TOOL_KIND_SPHERE,
      toolSize: { x: r, y: 0, z: 0 },
      speed: Math.max(0.01, strength * maxSpeed * 0.25),
      amount: kind === v1.EditKind.EDIT_KIND_SMOOTH ? 4 * strength
        : (kind === v1.EditKind.EDIT_KIND_INFLATE || kind === v1.EditKind.EDIT_KIND_DEFLATE) ? 0.5 * r * strength : 0,
      origin: packed.origin,
      t0Ms: packed.t0,
      poseCount: poses.length,
      poses: packed.bytes,
    };
    // Kept until acknowledged: sent now, or after a reconnection, and resent after one.
    if (!this.app.outbox.open) this.app.stats.strokesQueued = (this.app.stats.strokesQueued || 0) + 1;
    this.app.outbox.add('stroke', stroke, poses.length);
    this.pending.set(stroke.clientSeq, performance.now());
    this.gestureOf.set(stroke.clientSeq, this.gesture);
    this.app.stats.strokesSent += 1;
    this.app.stats.posesSent = (this.app.stats.posesSent || 0) + poses.length;
  }

  /** A paint at the newest sample: the material under the tool, weighted by strength and pressure. */
  flushPaint() {
    const p = this.samples[this.samples.length - 1];
    this.samples = [];
    const r = this.radius();
    const paint = {
      clientSeq: ++this.seq,
      object: this.object.name,
      tool: v1.ToolKind.TOOL_KIND_SPHERE,
      toolSize: { x: r, y: 0, z: 0 },
      position: { x: p.x, y: p.y, z: p.z },
      material: Number($('tool-material').value),
      weight: Math.min(1, Number($('tool-strength').value) * Math.min(1, 2 * this.pressure)),
    };
    this.app.outbox.add('paint', paint);
    this.pendingPaints.set(paint.clientSeq, performance.now());
    this.app.stats.paintsSent += 1;
  }

  /** A latency worth recording: not one that includes a reconnection (the request was resent). */
  recordLatency(seq, sent) {
    const e = this.app.outbox.entries.get(seq);
    if (sent === undefined || (e && e.resends > 0)) return;
    this.app.stats.ackLatencies.push(performance.now() - sent);
    if (this.app.stats.ackLatencies.length > 2000) this.app.stats.ackLatencies.shift();
  }

  onPaintAck(ack) {
    const seq = num(ack.clientSeq);
    // Refused by a member that lost the scene: the paint is resent after the reconnection.
    if (!ack.accepted && isUnavailable(ack.error)) return;
    const sent = this.pendingPaints.get(seq);
    this.pendingPaints.delete(seq);
    if (ack.accepted) this.recordLatency(seq, sent);
    this.app.outbox.settle(seq);
    if (ack.accepted) {
      this.app.stats.paintsAcked += 1;
      this.app.stats.globalSeq = Math.max(this.app.stats.globalSeq, num(ack.globalSeq));
    }
  }

  onAck(ack) {
    const seq = num(ack.clientSeq);
    const sent = this.pending.get(seq);
    if (sent === undefined) return;  // not this page's, or answered already
    this.recordLatency(seq, sent);
    this.pending.delete(seq);
    this.app.outbox.settle(seq);
    this.app.stats.acks += 1;
    if (ack.duplicate) this.app.stats.duplicateAcks = (this.app.stats.duplicateAcks || 0) + 1;
    const edits = ack.edits || 0;
    if (edits > 0) {
      this.app.stats.globalSeq = Math.max(this.app.stats.globalSeq, num(ack.globalSeqFirst) + edits - 1);
    }
    this.clearTrailWhenDone();
  }

  /**
   * A stroke refused for good (a limit, a bad value): it is not kept. An UNAVAILABLE refusal
   * (a cluster member that does not hold the scene now) is not final: main.js reconnects and
   * the stroke is resent.
   */
  onError(e) {
    const seq = num(e.clientSeq);
    if (seq === 0 || isUnavailable(e) || !this.pending.has(seq)) return;
    this.pending.delete(seq);
    this.gestureOf.delete(seq);
    this.app.outbox.settle(seq);
    this.app.stats.strokesRefused = (this.app.stats.strokesRefused || 0) + 1;
    this.clearTrailWhenDone();
  }

  clearTrailWhenDone() {
    if (this.pending.size === 0 && !this.dragging) {
      // The server's chunks now show what the trail stood in for.
      setTimeout(() => { if (!this.dragging) { this.trailPoints = []; this.trail.geometry.setFromPoints([]); this.app.invalidate(); } }, 300);
    }
  }
}

export class Presence {
  constructor(scene, list) {
    this.scene = scene;
    this.list = list;
    this.ownSession = 0;
    this.shapes = new Map();  // session -> mesh
    this.entries = [];
  }

  update(presence) {
    this.entries = presence.users.map((u) => ({ session: num(u.sessionId), name: u.name,
      colour: u.colorRgba >>> 0, role: u.role, position: u.position, radius: u.radius }));
    const seen = new Set();
    this.list.textContent = '';
    for (const u of this.entries) {
      const li = document.createElement('li');
      const own = u.session === this.ownSession;
      li.textContent = `${u.name}${own ? ' (you)' : ''}${u.role === v1.Role.ROLE_VIEWER ? ' · viewer' : ''}`;
      li.style.color = `#${(u.colour >>> 8).toString(16).padStart(6, '0')}`;
      this.list.appendChild(li);
      if (own || !u.position || !(u.radius > 0)) continue;
      seen.add(u.session);
      let shape = this.shapes.get(u.session);
      if (!shape) {
        shape = new THREE.Mesh(new THREE.SphereGeometry(1, 20, 14),
          new THREE.MeshBasicMaterial({ transparent: true, opacity: 0.35, depthWrite: false }));
        this.scene.add(shape);
        this.shapes.set(u.session, shape);
      }
      shape.material.color.setHex(u.colour >>> 8);
      shape.position.set(u.position.x, u.position.y, u.position.z);
      shape.scale.setScalar(u.radius);
      shape.userData.name = u.name;
    }
    for (const [session, shape] of this.shapes) {
      if (seen.has(session)) continue;
      this.scene.remove(shape);
      this.shapes.delete(session);
    }
  }

  /** Other people's tools being drawn: [{name, position, radius}]. */
  others() {
    return [...this.shapes.values()].map((s) => ({ name: s.userData.name,
      position: { x: s.position.x, y: s.position.y, z: s.position.z }, radius: s.scale.x }));
  }
}
