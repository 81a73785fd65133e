// The connection to sculptd: one WebSocket on /ws carrying ClientMessage / ServerMessage, one
// serialized message per binary WebSocket message (proto/README.md, "WebSocket").
import * as pb from '../gen/sculpt_pb.js';

export const v1 = pb.sculpt.v1;

/** A protobuf 64-bit field as a JavaScript number (Long, BigInt or number). */
export function num(x) {
  if (x === null || x === undefined) return 0;
  if (typeof x === 'number') return x;
  if (typeof x === 'bigint') return Number(x);
  if (typeof x.toNumber === 'function') return x.toNumber();
  return Number(x);
}

// At most this many cluster members' addresses are kept from a SceneInfo.
export const kMaxClusterMembers = 64;

/** Whether `text` is HOST:PORT: a host name, an IPv4 address or a bracketed IPv6 one, port 1..65535. */
export function isHostPort(text) {
  if (typeof text !== 'string' || text.length === 0 || text.length > 300) return false;
  const m = /^(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?):([0-9]{1,5})$/.exec(text);
  if (!m) return false;
  const port = Number(m[2]);
  return port >= 1 && port <= 65535;
}

/**
 * SceneInfo.cluster_members' HTTP addresses (cluster mode): the live members as the member that
 * answered the join read them, its own included, to rejoin through when it dies. What a server
 * says is checked like any input: entries that are not HOST:PORT (a member without an HTTP port
 * has none) are skipped, duplicates dropped, at most `max` kept, in the order given.
 */
export function clusterHttpAddresses(info, max = kMaxClusterMembers) {
  const out = [];
  const members = (info && Array.isArray(info.clusterMembers)) ? info.clusterMembers : [];
  for (const m of members) {
    if (out.length >= max) break;
    const address = m && m.httpAddress;
    if (isHostPort(address) && !out.includes(address)) out.push(address);
  }
  return out;
}

const kErrorNames = Object.fromEntries(Object.entries(v1.ErrorCode).map(([k, v]) => [v, k]));

/** "INVALID_ARGUMENT Stroke.tool_size.x=40 outside [0.5, 16]: message" */
export function describeError(e) {
  const code = (kErrorNames[e.code] || `code ${e.code}`).replace(/^ERROR_CODE_/, '');
  let text = code;
  if (e.field) text += ` ${e.field}`;
  if (e.value) text += `=${e.value}`;
  if (e.allowedRange) text += ` outside ${e.allowedRange}`;
  if (e.message) text += `: ${e.message}`;
  return text;
}

export class Connection extends EventTarget {
  constructor(url = '') {
    super();
    this.url = url;
    this.ws = null;
    this.bytesIn = 0;
    this.bytesOut = 0;
    this.state = 'closed';
  }

  /**
   * Opens the socket on `url` (or the last one). One Connection serves the page for its life:
   * a redirect or a reconnection opens a new socket on it, so the listeners stay. Events of an
   * earlier socket (one this page closed, or replaced) are dropped.
   */
  open(url = this.url) {
    this.url = url;
    // A socket left from a join that failed half-way (a refusal, a timeout) is closed.
    const old = this.detach();
    if (old && old.readyState <= WebSocket.OPEN) old.close(1000, 'superseded');
    return new Promise((resolve, reject) => {
      const ws = new WebSocket(this.url);
      ws.binaryType = 'arraybuffer';
      this.ws = ws;
      this.state = 'connecting';
      const live = () => this.ws === ws;
      ws.onopen = () => { if (live()) { this.state = 'open'; resolve(); } };
      ws.onerror = () => { if (live() && this.state === 'connecting') reject(new Error(`cannot connect to ${this.url}`)); };
      ws.onclose = (ev) => {
        if (!live()) return;
        const wasConnecting = this.state === 'connecting';
        this.state = 'closed';
        this.ws = null;
        if (wasConnecting) reject(new Error(`cannot connect to ${this.url}`));
        this.dispatchEvent(new CustomEvent('close', { detail: { code: ev.code, reason: ev.reason } }));
      };
      ws.onmessage = (ev) => {
        if (!live() || !(ev.data instanceof ArrayBuffer)) return;
        this.bytesIn += ev.data.byteLength;
        let msg;
        try {
          msg = v1.ServerMessage.decode(new Uint8Array(ev.data));
        } catch (err) {
          this.dispatchEvent(new CustomEvent('protocol-error', { detail: String(err) }));
          return;
        }
        if (msg.body) this.dispatchEvent(new CustomEvent(msg.body, { detail: msg[msg.body] }));
      };
    });
  }

  /** Forgets the current socket: nothing it still delivers reaches the listeners. */
  detach() {
    const ws = this.ws;
    this.ws = null;
    this.state = 'closed';
    if (ws) { ws.onopen = ws.onerror = ws.onclose = ws.onmessage = null; }
    return ws;
  }

  /** Sends one ClientMessage: `body` is the oneof field name, `value` its plain object. */
  send(body, value) {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    const bytes = v1.ClientMessage.encode(v1.ClientMessage.create({ [body]: value })).finish();
    this.bytesOut += bytes.length;
    this.ws.send(bytes);
    return true;
  }

  /** Resolves with the first `type` message, rejects on an Error message or a close first. */
  next(type, timeoutMs = 10000) {
    return this.nextOf([type], timeoutMs).then((m) => m.detail);
  }

  /**
   * Resolves with { type, detail } of the first message of one of `types` (a JoinScene is
   * answered by sceneInfo or redirect); rejects on an Error message or a close first.
   */
  nextOf(types, timeoutMs = 10000) {
    return new Promise((resolve, reject) => {
      const handlers = types.map((type) => [type, (ev) => done(resolve, { type, detail: ev.detail })]);
      const done = (fn, arg) => {
        clearTimeout(timer);
        for (const [type, h] of handlers) this.removeEventListener(type, h);
        this.removeEventListener('error', onError);
        this.removeEventListener('close', onClose);
        fn(arg);
      };
      const onError = (ev) => done(reject, Object.assign(new Error(describeError(ev.detail)), { wire: ev.detail }));
      const onClose = (ev) => done(reject, new Error(`connection closed ${ev.detail.reason || ''}`.trim()));
      const timer = setTimeout(() => done(reject, new Error(`no ${types.join(' or ')} within ${timeoutMs} ms`)),
        timeoutMs);
      for (const [type, h] of handlers) this.addEventListener(type, h);
      this.addEventListener('error', onError);
      this.addEventListener('close', onClose);
    });
  }

  /** Says Bye and closes the socket; no 'close' event follows (the page chose it). */
  close(reason = 'page closed') {
    const ws = this.ws;
    if (ws && ws.readyState === WebSocket.OPEN) this.send('bye', { reason });
    this.detach();
    if (ws && (ws.readyState === WebSocket.OPEN || ws.readyState === WebSocket.CONNECTING)) ws.close(1000, reason.slice(0, 100));
  }

  get isOpen() { return !!this.ws && this.ws.readyState === WebSocket.OPEN; }
}

// Seconds of Welcome.max_strokes_per_second a JoinScene declares as resends at most.
export const kDeclaredResendSeconds = 5;

// The ClientMessage body of each kind of edit the outbox keeps -> its EditStream.
const kEditStreams = {
  stroke: v1.EditStream.EDIT_STREAM_STROKES,
  paint: v1.EditStream.EDIT_STREAM_PAINTS,
  modelIntent: v1.EditStream.EDIT_STREAM_MODELS,
  skinBallEdit: v1.EditStream.EDIT_STREAM_BALL_EDITS,
  skinSweep: v1.EditStream.EDIT_STREAM_SWEEPS,
  undo: v1.EditStream.EDIT_STREAM_UNDOS,
};

/**
 * The edits this page sent that the server has not answered yet (strokes, paints, undos: each
 * kept with its message until its ack or a final refusal), in the order they were made, and
 * the ones waiting to go out. A cluster member that loses a scene refuses an edit with
 * UNAVAILABLE and every later one of this client until it is resent in order (the server's
 * ResendStream fence); the scene's owner acknowledges a resend of an edit it already applied as
 * a duplicate. So after a reconnection every unanswered edit goes again, oldest first, with its
 * own client_seq, before any newer one, and at a pace under the server's per-client rate limits
 * (a refused resend cannot be sent again once a later edit is applied: it would be taken for a
 * duplicate). While the page is reconnecting, new edits wait here.
 */
export class Outbox {
  /**
   * `send(body, value)` puts one message on the wire (false: not connected); `rate` bounds the
   * sending of a backlog: { strokesPerSecond, strokeBurst, posesPerSecond, poseBurst }, each
   * request taking one stroke token (the server charges paints and undos one too) and a stroke
   * also one pose token per pose; `now()` in ms.
   */
  constructor(send, rate, now = () => performance.now()) {
    this.sendMessage = send;
    this.rate = rate;
    this.now = now;
    this.entries = new Map();  // client_seq -> { body, value, poses, sentAt, resends }
    this.waiting = [];  // client_seqs to write on the current connection, in order
    this.open = false;
    this.strokeTokens = rate.strokeBurst;
    this.poseTokens = rate.poseBurst;
    this.refilledAt = now();
    this.timer = null;
    this.resent = 0;  // requests written again after a reconnection, in all
    this.onEmpty = null;  // called when the last unanswered request is answered
  }

  get size() { return this.entries.size; }

  /** Keeps `value` (its clientSeq unique among this page's requests) and sends it when it may. */
  add(body, value, poses = 0) {
    const seq = num(value.clientSeq);
    this.entries.set(seq, { body, value, poses, written: false, sentAt: 0, resends: 0 });
    this.waiting.push(seq);
    this.drain();
    return seq;
  }

  /** The request's answer came (an ack, a duplicate ack or a final refusal): forgets it. */
  settle(seq) {
    const e = this.entries.get(seq);
    this.entries.delete(seq);
    if (e && this.entries.size === 0 && this.onEmpty) this.onEmpty();
    return e;
  }

  /** The connection is gone or refused: nothing goes out until `resume`, which resends all. */
  hold() {
    this.open = false;
    clearTimeout(this.timer);
    this.timer = null;
  }

  /**
   * A new connection is joined: every unanswered request is written again in order (the ones
   * never written included), paced. Returns how many are resent (written before).
   */
  resume() {
    const seqs = [...this.entries.keys()].sort((a, b) => a - b);
    let resent = 0;
    for (const seq of seqs) {
      const e = this.entries.get(seq);
      if (e.written) { e.resends += 1; resent += 1; }
    }
    this.waiting = seqs;
    this.resent += resent;
    this.open = true;
    this.drain();
    return resent;
  }

  /** Writes waiting requests while the connection is open and the pace allows. */
  drain() {
    if (!this.open) return;
    clearTimeout(this.timer);
    this.timer = null;
    this.refill();
    while (this.waiting.length > 0) {
      const e = this.entries.get(this.waiting[0]);
      if (!e) { this.waiting.shift(); continue; }
      const poses = Math.min(e.poses, this.rate.poseBurst);
      if (this.strokeTokens < 1 || this.poseTokens < poses) {
        const ms = 1000 * Math.max((1 - this.strokeTokens) / this.rate.strokesPerSecond,
          (poses - this.poseTokens) / this.rate.posesPerSecond);
        this.timer = setTimeout(() => this.drain(), Math.max(1, Math.ceil(ms)));
        return;
      }
      if (!this.sendMessage(e.body, e.value)) { this.open = false; return; }
      this.strokeTokens -= 1;
      this.poseTokens -= poses;
      e.written = true;
      e.sentAt = this.now();
      this.waiting.shift();
    }
  }

  refill() {
    const t = this.now();
    const dt = Math.max(0, t - this.refilledAt) / 1000;
    this.refilledAt = t;
    this.strokeTokens = Math.min(this.rate.strokeBurst, this.strokeTokens + dt * this.rate.strokesPerSecond);
    this.poseTokens = Math.min(this.rate.poseBurst, this.poseTokens + dt * this.rate.posesPerSecond);
  }

  /**
   * JoinScene.resends: the client_seq ranges of the unanswered requests `resume` will write,
   * oldest first, one range per stream ({ stream, firstSeq, lastSeq }), so the server lets them
   * through its rate limits without tokens (proto/README.md, "Declared resends"). Strokes,
   * paints and undos share this page's counter, so a stream's range spans the others'
   * sequences; all ranges together stay within `max` sequences (the server allows a connection
   * stroke_burst + 5 s of strokes; the page knows the rate only, so 5 s of it). Requests past
   * the bound are resent all the same, and charged.
   */
  resendRanges(max) {
    const ranges = new Map();  // stream -> range
    let declared = 0;
    for (const seq of [...this.entries.keys()].sort((a, b) => a - b)) {
      const stream = kEditStreams[this.entries.get(seq).body];
      if (!stream) break;  // a kind the server has no resend stream for: keep the order simple
      const r = ranges.get(stream);
      const cost = r ? seq - r.lastSeq : 1;
      if (declared + cost > max) break;
      declared += cost;
      if (r) r.lastSeq = seq;
      else ranges.set(stream, { stream, firstSeq: seq, lastSeq: seq });
    }
    return [...ranges.values()];
  }

  /** The requests not yet answered, by kind: { stroke: 3, undo: 1 }. */
  counts() {
    const c = {};
    for (const e of this.entries.values()) c[e.body] = (c[e.body] || 0) + 1;
    return c;
  }
}
