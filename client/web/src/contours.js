// The thin-client view: a 2D panel per ball skin (its contour decoded from the contour codec,
// its balls drawn and, for sculptors, dragged with ball edits over the wire) and a slice of an
// object on a chosen axis plane. Both follow ContourUpdate messages of a ContourSubscribe.
import * as THREE from 'three';
import { ContourView, decodeContours } from './contour_codec.js';
import { num, v1 } from './connection.js';

const kEditHz = 15;          // ball edits while dragging, at most
const kSliceSamples = 200;   // samples across a slice's square

/** Maps plane coordinates onto a canvas, y up, keeping the aspect ratio. */
class PlaneFrame {
  constructor(canvas) { this.canvas = canvas; this.fit(-1, -1, 1, 1); }

  fit(x0, y0, x1, y1) {
    const w = this.canvas.width, h = this.canvas.height, m = 10;
    const sx = (w - 2 * m) / Math.max(1e-9, x1 - x0), sy = (h - 2 * m) / Math.max(1e-9, y1 - y0);
    this.s = Math.min(sx, sy);
    this.cx = (x0 + x1) / 2;
    this.cy = (y0 + y1) / 2;
  }

  toCanvas(x, y) {
    return [this.canvas.width / 2 + (x - this.cx) * this.s, this.canvas.height / 2 - (y - this.cy) * this.s];
  }

  toPlane(px, py) {
    return [this.cx + (px - this.canvas.width / 2) / this.s, this.cy - (py - this.canvas.height / 2) / this.s];
  }
}

/** Strokes a polyline (interleaved x, y); returns the points drawn. */
function drawPolyline(ctx, frame, line, closed = false) {
  const n = line.length / 2;
  if (n === 0) return 0;
  ctx.beginPath();
  for (let i = 0; i < n; ++i) {
    const [x, y] = frame.toCanvas(line[2 * i], line[2 * i + 1]);
    if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
  }
  if (closed) ctx.closePath();
  ctx.stroke();
  return n;
}

function canvasPoint(canvas, e) {
  const r = canvas.getBoundingClientRect();
  return [(e.clientX - r.left) * (canvas.width / r.width), (e.clientY - r.top) * (canvas.height / r.height)];
}

/** One skin: its contour, its balls, ball dragging, and its outline in the 3D view. */
export class SkinPanel {
  constructor(app, info, container, canEdit) {
    this.app = app;
    this.name = info.name;
    this.origin = new THREE.Vector3(info.origin?.x || 0, info.origin?.y || 0, info.origin?.z || 0);
    this.u = new THREE.Vector3(info.u?.x || 1, info.u?.y || 0, info.u?.z || 0);
    this.v = new THREE.Vector3(info.v?.x || 0, info.v?.y || 1, info.v?.z || 0);
    this.canEdit = canEdit;
    this.view = new ContourView();
    this.balls = [];
    this.version = 0;
    this.updates = 0;
    this.decodedPoints = 0;   // points in the sections the view holds
    this.drawnPoints = 0;     // points the last drawing stroked
    this.editsSent = 0;
    this.editsAccepted = 0;
    this.refused = 0;
    this.drag = null;
    const box = document.createElement('section');
    box.className = 'contour';
    box.innerHTML = `<h3></h3><canvas width="240" height="150"></canvas><p class="hint"></p>`;
    box.querySelector('h3').textContent = `skin ${this.name}`;
    box.querySelector('.hint').textContent = canEdit ? 'drag a ball to move it, shift-drag to resize' : '';
    container.appendChild(box);
    this.canvas = box.querySelector('canvas');
    this.canvas.dataset.skin = this.name;
    this.frame = new PlaneFrame(this.canvas);
    this.outline = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xffb347 }));
    app.scene.add(this.outline);
    if (canEdit) {
      this.canvas.addEventListener('pointerdown', (e) => this.down(e));
      this.canvas.addEventListener('pointermove', (e) => this.move(e));
      this.canvas.addEventListener('pointerup', (e) => this.up(e));
      this.canvas.addEventListener('pointercancel', (e) => this.up(e));
    }
  }

  /** A ContourUpdate for this skin: a snapshot or an update, with the chain of balls. */
  onUpdate(u) {
    this.view.apply(u.data);
    this.version = num(u.skinVersion);
    this.updates += 1;
    if (u.balls && u.balls.length) this.balls = u.balls.map((b) => ({ x: b.x, y: b.y, r: b.r, theta: b.theta }));
    this.decodedPoints = this.view.sections.reduce((s, c) => s + c.plus.length / 2 + c.minus.length / 2, 0);
    if (!this.drag) this.refit();
    this.draw();
    this.updateOutline();
  }

  refit() {
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    const grow = (x, y) => { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); };
    for (const b of this.balls) { grow(b.x - b.r, b.y - b.r); grow(b.x + b.r, b.y + b.r); }
    for (const s of this.view.sections) {
      for (const line of [s.plus, s.minus]) for (let i = 0; i < line.length; i += 2) grow(line[i], line[i + 1]);
    }
    if (x0 <= x1) {
      const m = 0.1 * Math.max(x1 - x0, y1 - y0);
      this.frame.fit(x0 - m, y0 - m, x1 + m, y1 + m);
    }
  }

  draw() {
    const ctx = this.canvas.getContext('2d');
    ctx.fillStyle = '#15171b';
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.lineWidth = 1;
    ctx.strokeStyle = '#566070';
    this.balls.forEach((b, i) => {
      const [x, y] = this.frame.toCanvas(b.x, b.y);
      ctx.strokeStyle = this.drag && this.drag.index === i ? '#7fd0ff' : '#566070';
      ctx.beginPath();
      ctx.arc(x, y, b.r * this.frame.s, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.fillStyle = ctx.strokeStyle;
      ctx.fillRect(x - 2, y - 2, 4, 4);
    });
    let drawn = 0;
    ctx.lineWidth = 1.5;
    for (const s of this.view.sections) {
      ctx.strokeStyle = '#ffb347';
      drawn += drawPolyline(ctx, this.frame, s.plus);
      ctx.strokeStyle = '#e07a5f';
      drawn += drawPolyline(ctx, this.frame, s.minus);
    }
    this.drawnPoints = drawn;
    ctx.fillStyle = '#9aa3ad';
    ctx.font = '11px system-ui';
    ctx.fillText(`v${this.version}  ${this.balls.length} balls  ${this.decodedPoints} points`, 6, 14);
  }

  /** The + chain and the reversed - chain as one closed outline on the skin's plane in 3D. */
  updateOutline() {
    const pts = [];
    const add = (line) => {
      for (let i = 0; i < line.length; i += 2) {
        pts.push(this.origin.clone().addScaledVector(this.u, line[i]).addScaledVector(this.v, line[i + 1]));
      }
    };
    add(this.view.chain(1));
    const minus = this.view.chain(-1);
    const reversed = new Float64Array(minus.length);
    for (let i = 0; i < minus.length; i += 2) {
      reversed[minus.length - 2 - i] = minus[i];
      reversed[minus.length - 1 - i] = minus[i + 1];
    }
    add(reversed);
    if (pts.length) pts.push(pts[0].clone());
    this.outline.geometry.setFromPoints(pts);
    this.app.invalidate();
  }

  ballAt(px, py) {
    let best = -1, bestD = Infinity;
    this.balls.forEach((b, i) => {
      const [x, y] = this.frame.toCanvas(b.x, b.y);
      const d = Math.hypot(px - x, py - y);
      if (d <= Math.max(8, b.r * this.frame.s) && d < bestD) { best = i; bestD = d; }
    });
    return best;
  }

  down(e) {
    const [px, py] = canvasPoint(this.canvas, e);
    const index = this.ballAt(px, py);
    if (index < 0) return;
    const b = this.balls[index];
    const [x, y] = this.frame.toPlane(px, py);
    this.drag = { index, resize: e.shiftKey, dx: b.x - x, dy: b.y - y, r0: b.r, d0: Math.hypot(x - b.x, y - b.y), last: 0, pending: null };
    this.canvas.setPointerCapture(e.pointerId);
    this.draw();
  }

  move(e) {
    if (!this.drag) return;
    const [px, py] = canvasPoint(this.canvas, e);
    const [x, y] = this.frame.toPlane(px, py);
    const b = this.balls[this.drag.index];
    if (!b) return;
    const next = { ...b };
    if (this.drag.resize) {
      next.r = Math.max(1e-3, this.drag.r0 + Math.hypot(x - b.x, y - b.y) - this.drag.d0);
    } else {
      next.x = x + this.drag.dx;
      next.y = y + this.drag.dy;
    }
    this.drag.pending = next;
    const now = performance.now();
    if (now - this.drag.last >= 1000 / kEditHz) this.sendPending(now);
  }

  up() {
    if (!this.drag) return;
    this.sendPending(performance.now());
    this.drag = null;
    this.refit();
    this.draw();
  }

  sendPending(now) {
    const d = this.drag;
    if (!d || !d.pending) return;
    d.last = now;
    const b = d.pending;
    d.pending = null;
    const clientSeq = ++this.app.skinEditSeq;
    if (this.app.conn.send('skinBallEdit', { clientSeq, skin: this.name, op: v1.SkinBallOp.SKIN_BALL_OP_MOVE,
      index: d.index, ball: { x: b.x, y: b.y, r: b.r, theta: b.theta } })) {
      this.editsSent += 1;
      this.app.pendingSkinEdits.set(clientSeq, this);
    }
  }

  stats() {
    return { name: this.name, version: this.version, updates: this.updates, balls: this.balls.map((b) => ({ ...b })),
      sections: this.view.sections.length, decodedPoints: this.decodedPoints, drawnPoints: this.drawnPoints,
      editsSent: this.editsSent, editsAccepted: this.editsAccepted, refused: this.refused };
  }
}

/** A cut of an object by an axis plane, redrawn after every edit that crosses it. */
export class SlicePanel {
  constructor(app, object, container) {
    this.app = app;
    this.object = object;
    this.lines = [];
    this.globalSeq = 0;
    this.updates = 0;
    this.points = 0;
    const lo = object.boundsMin || { x: -1, y: -1, z: -1 }, hi = object.boundsMax || { x: 1, y: 1, z: 1 };
    this.lo = lo;
    this.hi = hi;
    const box = document.createElement('section');
    box.className = 'contour';
    box.innerHTML = `<h3></h3>
      <label>Plane <select class="slice-axis"><option value="z">z</option><option value="y">y</option><option value="x">x</option></select>
      <input class="slice-offset" type="range" min="0" max="1" step="0.01" value="0.5"></label>
      <canvas width="240" height="150"></canvas>`;
    box.querySelector('h3').textContent = `slice of ${object.name}`;
    container.appendChild(box);
    this.canvas = box.querySelector('canvas');
    this.axis = box.querySelector('.slice-axis');
    this.offset = box.querySelector('.slice-offset');
    this.frame = new PlaneFrame(this.canvas);
    this.axis.addEventListener('change', () => this.subscribe());
    this.offset.addEventListener('change', () => this.subscribe());
    this.subscribe();
  }

  /** The plane the controls choose: origin on the axis through the bounds' centre, u and v in-plane. */
  plane() {
    const a = this.axis.value;
    const t = Number(this.offset.value);
    const c = { x: (this.lo.x + this.hi.x) / 2, y: (this.lo.y + this.hi.y) / 2, z: (this.lo.z + this.hi.z) / 2 };
    c[a] = this.lo[a] + t * (this.hi[a] - this.lo[a]);
    const axes = { x: [{ x: 0, y: 1, z: 0 }, { x: 0, y: 0, z: 1 }], y: [{ x: 0, y: 0, z: 1 }, { x: 1, y: 0, z: 0 }],
      z: [{ x: 1, y: 0, z: 0 }, { x: 0, y: 1, z: 0 }] }[a];
    const half = 0.5 * Math.max(this.hi.x - this.lo.x, this.hi.y - this.lo.y, this.hi.z - this.lo.z);
    return { origin: c, u: axes[0], v: axes[1], halfExtent: half, step: (2 * half) / kSliceSamples };
  }

  subscribe() {
    if (this.current) this.app.conn.send('contourSubscribe', { slice: this.current, unsubscribe: true });
    const p = this.plane();
    this.current = { object: this.object.name, ...p };
    this.lines = [];
    this.frame.fit(-p.halfExtent, -p.halfExtent, p.halfExtent, p.halfExtent);
    this.app.conn.send('contourSubscribe', { slice: this.current });
    this.draw();
  }

  onUpdate(u) {
    this.lines = decodeContours(u.data);
    this.globalSeq = num(u.globalSeq);
    this.updates += 1;
    this.points = this.lines.reduce((s, l) => s + l.length / 2, 0);
    this.draw();
  }

  draw() {
    const ctx = this.canvas.getContext('2d');
    ctx.fillStyle = '#15171b';
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.strokeStyle = '#7fd0ff';
    ctx.lineWidth = 1.5;
    for (const l of this.lines) drawPolyline(ctx, this.frame, l);
    ctx.fillStyle = '#9aa3ad';
    ctx.font = '11px system-ui';
    ctx.fillText(`${this.axis.value} plane  seq ${this.globalSeq}  ${this.lines.length} curves`, 6, 14);
  }

  stats() {
    return { object: this.object.name, updates: this.updates, curves: this.lines.length, points: this.points,
      globalSeq: this.globalSeq };
  }
}

/** Every skin panel and the slice panel of a session, fed from its ContourUpdate messages. */
export class Contours {
  constructor(app, info, canEdit) {
    this.app = app;
    this.skins = new Map();
    this.slice = null;
    const container = document.getElementById('contours');
    container.hidden = false;
    for (const s of info.skins || []) {
      this.skins.set(s.name, new SkinPanel(app, s, container, canEdit));
      app.conn.send('contourSubscribe', { skin: s.name });
    }
    if (info.objects.length) this.slice = new SlicePanel(app, info.objects[0], container);
    app.conn.addEventListener('contour', (ev) => this.onContour(ev.detail));
    app.conn.addEventListener('skinAck', (ev) => this.onSkinAck(ev.detail));
  }

  onContour(u) {
    try {
      if (u.skin) this.skins.get(u.skin)?.onUpdate(u);
      else if (this.slice && u.object === this.slice.object.name) this.slice.onUpdate(u);
    } catch (err) {
      this.app.showError(`contour of ${u.skin || u.object} not decoded: ${err.message}`);
    }
  }

  onSkinAck(a) {
    const seq = num(a.clientSeq);
    const panel = this.app.pendingSkinEdits.get(seq);
    this.app.pendingSkinEdits.delete(seq);
    if (a.accepted) {
      if (panel) panel.editsAccepted += 1;
      return;
    }
    // A refused move leaves the skin as it was: the panel redraws the server's balls. The
    // refusal itself arrives as an Error too, which the page shows.
    if (panel) { panel.refused += 1; panel.refit(); panel.draw(); }
  }

  stats() {
    return { skins: [...this.skins.values()].map((p) => p.stats()), slice: this.slice ? this.slice.stats() : null };
  }
}
