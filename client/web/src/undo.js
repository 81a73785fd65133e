// Per-user undo and redo (issue 15): the Undo and Redo buttons and Ctrl+Z / Ctrl+Shift+Z (Cmd on
// a Mac; Ctrl+Y redoes too) take back, or put back, this page's own most recent drag. A drag
// leaves as several strokes (tools.js sends the samples 60 times a second), and the server undoes
// one stroke per UndoRequest, so a drag is taken back with one request per stroke it was sent
// as; the answers (UndoAck) are summed up in one short line: which drag, whose later edits the
// server replayed on top. Sculptors only: the buttons live in the tools panel, which viewers
// never see. The server stays the authority: a refusal (nothing to undo, beyond its history)
// is said as it comes.
import { describeError, num, v1 } from './connection.js';

const $ = (id) => document.getElementById(id);
const kKeptDrags = 64;     // drags kept for undo (the server keeps 64 strokes per author by default)
const kDeferMs = 2000;     // an undo waits this long at most for the drag's strokes to be acked

/**
 * An author as the server names it: the user on a server with named users, else the client id,
 * shown by its last digits ("sculptor …4821"); this page is "you".
 */
export function authorName(author, ownAuthor) {
  if (author === ownAuthor) return 'you';
  return /^\d+$/.test(author) ? `sculptor …${author.slice(-4)}` : author;
}

/** "3 later edits by alice replayed" / "5 later edits replayed (alice 3, you 2)" / "". */
export function describeReplayed(byAuthor, ownAuthor) {
  const who = [...byAuthor].map(([author, edits]) => ({ name: authorName(author, ownAuthor), edits }))
    .filter((w) => w.edits > 0);
  const n = who.reduce((sum, w) => sum + w.edits, 0);
  if (n === 0) return '';
  const edits = `${n} later edit${n === 1 ? '' : 's'}`;
  if (who.length === 1) return `${edits} by ${who[0].name} replayed`;
  return `${edits} replayed (${who.map((w) => `${w.name} ${w.edits}`).join(', ')})`;
}

/** Why an undo or redo was refused, in a few words. */
export function describeRefusal(error, redo) {
  const verb = redo ? 'redo' : 'undo';
  const e = error || {};
  const codes = v1.ErrorCode;
  if (e.code === codes.ERROR_CODE_FAILED_PRECONDITION) return `nothing to ${verb}`;
  if (e.code === codes.ERROR_CODE_INVALID_ARGUMENT) return `cannot ${verb} further: older edits fell off the history`;
  // An older sculptd: the message is unknown to it.
  if (e.code === codes.ERROR_CODE_MALFORMED) return `this server does not know ${verb}`;
  return `${verb} refused: ${describeError(e)}`;
}

/**
 * The line for the answers to one undo (or redo) of drag number `drag` (0: not a known drag):
 * `acks` are the UndoAcks of its requests in order. Later edits replayed by each author are
 * the most any one request replayed (the requests replay overlapping sets).
 */
export function describeUndo(acks, { redo, drag, ownAuthor, undoable, redoable }) {
  const done = acks.filter((a) => a.accepted);
  const refused = acks.find((a) => !a.accepted);
  if (done.length === 0) return describeRefusal(refused && refused.error, redo);
  const what = drag ? `your stroke #${drag}` : 'your last edit';
  let text = `${redo ? 'redone' : 'undone'}: ${what}`;
  if (refused) text += ` in part (${done.length} of ${acks.length} pieces: ${describeRefusal(refused.error, redo)})`;
  const byAuthor = new Map();
  for (const a of done) {
    for (const r of a.replayedBy || []) byAuthor.set(r.author, Math.max(byAuthor.get(r.author) || 0, r.edits || 0));
  }
  const replayed = describeReplayed(byAuthor, ownAuthor);
  if (replayed) text += `; ${replayed}`;
  return `${text}; ${undoable} more to undo, ${redoable} to redo`;
}

/** -1 for a key event that undoes, +1 for one that redoes, 0 otherwise. */
export function undoKey(e) {
  if (!(e.ctrlKey || e.metaKey) || e.altKey) return 0;
  const key = (e.key || '').toLowerCase();
  if (key === 'z') return e.shiftKey ? 1 : -1;
  if (key === 'y' && !e.shiftKey) return 1;
  return 0;
}

export class UndoControls {
  constructor(app, sculpting, welcome) {
    this.app = app;
    this.sculpting = sculpting;
    this.ownAuthor = String(num(welcome.clientId));  // the server files edits under this id
    this.done = [];    // acked drags, newest last: {drag, strokes}
    this.undone = [];  // undone drags, most recently undone last
    this.batch = null;   // the undo or redo in flight: {redo, entry, seqs, acks}
    this.deferred = null;  // an undo pressed while its drag's strokes were still unacked
    app.stats.undosSent = 0;
    app.stats.undoAcks = 0;
    app.stats.lastUndo = null;
    $('undo').addEventListener('click', () => this.request(false));
    $('redo').addEventListener('click', () => this.request(true));
    window.addEventListener('keydown', (e) => this.onKey(e));
    app.conn.addEventListener('ack', (ev) => this.onStrokeAck(ev.detail));
    app.conn.addEventListener('undoAck', (ev) => this.onUndoAck(ev.detail));
    app.conn.addEventListener('error', (ev) => this.onError(ev.detail));
  }

  onKey(e) {
    const dir = undoKey(e);
    if (dir === 0) return;
    const t = e.target;
    // A text field keeps its own undo.
    if (t && (t.isContentEditable || (t.tagName === 'INPUT' && t.type !== 'range') || t.tagName === 'TEXTAREA')) return;
    e.preventDefault();
    if (!e.repeat) this.request(dir > 0);
  }

  /** Undo (or redo) when the page is ready: not mid-drag, not mid-answer, strokes acked. */
  request(redo) {
    if (this.sculpting.dragging || this.batch) return;
    this.sculpting.flush();
    if (this.sculpting.pending.size > 0) {
      // The drag's last strokes are not acked yet: how many requests it needs is not known.
      this.deferred = { redo, until: performance.now() + kDeferMs };
      clearTimeout(this.deferTimer);
      this.deferTimer = setTimeout(() => this.runDeferred(true), kDeferMs);
      return;
    }
    this.send(redo);
  }

  runDeferred(force) {
    if (!this.deferred || (!force && this.sculpting.pending.size > 0)) return;
    const { redo } = this.deferred;
    this.deferred = null;
    clearTimeout(this.deferTimer);
    this.send(redo);
  }

  send(redo) {
    const entry = redo ? this.undone.pop() : this.done.pop();
    // Nothing known to take back: one request anyway, so the server's answer is what is said.
    const count = entry ? entry.strokes : 1;
    const seqs = [];
    for (let i = 0; i < count; ++i) {
      // Numbered with the strokes, so an Error's client_seq names one request (the server
      // de-duplicates undos on their own sequence: the gaps are harmless). Kept until answered,
      // and resent after a reconnection (main.js) like the strokes before it.
      const clientSeq = ++this.sculpting.seq;
      this.app.outbox.add('undo', { clientSeq, object: this.sculpting.object.name, redo });
      seqs.push(clientSeq);
    }
    this.app.stats.undosSent += seqs.length;
    this.batch = { redo, entry, seqs, acks: [] };
  }

  onStrokeAck(ack) {
    const seq = num(ack.clientSeq);
    const drag = this.sculpting.gestureOf.get(seq);
    this.sculpting.gestureOf.delete(seq);
    if (!ack.duplicate && (ack.edits || 0) > 0 && drag !== undefined) {
      const last = this.done[this.done.length - 1];
      if (last && last.drag === drag) last.strokes += 1;
      else this.done.push({ drag, strokes: 1 });
      if (this.done.length > kKeptDrags) this.done.shift();
      this.undone = [];  // a new stroke ends what can be redone, as on the server
    }
    if (this.sculpting.pending.size === 0) this.runDeferred(false);
  }

  onUndoAck(ack) {
    const b = this.batch;
    const seq = num(ack.clientSeq);
    if (!b || !b.seqs.includes(seq) || b.acks.some((a) => num(a.clientSeq) === seq)) return;
    // Refused by a member that lost the scene: resent after the reconnection, answered then.
    if (!ack.accepted && ack.error && ack.error.code === v1.ErrorCode.ERROR_CODE_UNAVAILABLE) return;
    this.app.outbox.settle(seq);
    b.acks.push(ack);
    this.app.stats.undoAcks += 1;
    if (ack.accepted && !ack.duplicate) {
      this.app.stats.globalSeq = Math.max(this.app.stats.globalSeq, num(ack.globalSeq));
    }
    if (b.acks.length < b.seqs.length) return;
    this.batch = null;
    const accepted = b.acks.filter((a) => a.accepted);
    if (b.entry && accepted.length > 0) {
      (b.redo ? this.done : this.undone).push({ drag: b.entry.drag, strokes: accepted.length });
    }
    const text = describeUndo(b.acks, { redo: b.redo, drag: b.entry ? b.entry.drag : 0, ownAuthor: this.ownAuthor,
      undoable: this.done.length, redoable: this.undone.length });
    const refused = b.acks.find((a) => !a.accepted);
    this.app.stats.lastUndo = { accepted: !refused, redo: b.redo, requests: b.acks.length,
      targetSeqs: accepted.map((a) => num(a.targetSeq)).sort((x, y) => x - y),
      globalSeq: Math.max(0, ...accepted.map((a) => num(a.globalSeq))),
      errorCode: refused && refused.error ? refused.error.code : 0, text };
    this.say(text);
  }

  /** An Error for a request in flight (the rate limit; a server that does not know undo). */
  onError(e) {
    const b = this.batch;
    if (!b || e.code === v1.ErrorCode.ERROR_CODE_UNAVAILABLE) return;
    const unknownBody = e.code === v1.ErrorCode.ERROR_CODE_MALFORMED && e.field === 'ClientMessage.body';
    const seq = num(e.clientSeq);
    if (!unknownBody && !b.seqs.includes(seq)) return;
    const open = unknownBody ? b.seqs.filter((s) => !b.acks.some((a) => num(a.clientSeq) === s)) : [seq];
    for (const s of open) this.onUndoAck({ clientSeq: s, accepted: false, redo: b.redo, error: e });
  }

  say(text) {
    $('undo-status').textContent = text;
  }
}
