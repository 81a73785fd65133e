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
  constructor(url) {
    super();
    this.url = url;
    this.ws = null;
    this.bytesIn = 0;
    this.bytesOut = 0;
    this.state = 'closed';
  }

  open() {
    return new Promise((resolve, reject) => {
      const ws = new WebSocket(this.url);
      ws.binaryType = 'arraybuffer';
      this.ws = ws;
      this.state = 'connecting';
      ws.onopen = () => { this.state = 'open'; resolve(); };
      ws.onerror = () => { if (this.state === 'connecting') reject(new Error(`cannot connect to ${this.url}`)); };
      ws.onclose = (ev) => {
        this.state = 'closed';
        this.dispatchEvent(new CustomEvent('close', { detail: { code: ev.code, reason: ev.reason } }));
      };
      ws.onmessage = (ev) => {
        if (!(ev.data instanceof ArrayBuffer)) return;
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

  close(reason = 'page closed') {
    if (this.ws && this.ws.readyState === WebSocket.OPEN) {
      this.send('bye', { reason });
      this.ws.close(1000, reason);
    }
  }
}
