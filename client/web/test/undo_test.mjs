// The web client's undo line and keys (client/web/src/undo.js) in node, without a browser or a
// server: what it says for accepted, partial and refused answers, and which keys undo and redo.
// Needs the generated protobuf code (client/web/gen, written by build.mjs). Usage:
//   node test/undo_test.mjs
import { authorName, describeRefusal, describeUndo, undoKey } from '../src/undo.js';
import { v1 } from '../src/connection.js';

let failures = 0;
function expect(name, got, want) {
  const ok = JSON.stringify(got) === JSON.stringify(want);
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}${ok ? '' : `: got ${JSON.stringify(got)}, want ${JSON.stringify(want)}`}`);
  if (!ok) failures += 1;
}

const E = v1.ErrorCode;
const ok = (target, replayedBy = []) => ({ accepted: true, targetSeq: target, replayedBy,
  replayed: replayedBy.reduce((s, r) => s + r.edits, 0) });
const refused = (code) => ({ accepted: false, error: { code, message: 'm' } });
const ctx = { redo: false, drag: 3, ownAuthor: '777', undoable: 2, redoable: 1 };

expect('one stroke, nothing replayed', describeUndo([ok(9)], ctx),
  'undone: your stroke #3; 2 more to undo, 1 to redo');
expect('replayed by one author, the most any request replayed',
  describeUndo([ok(9, [{ author: 'alice', edits: 3 }]), ok(8, [{ author: 'alice', edits: 2 }])], ctx),
  'undone: your stroke #3; 3 later edits by alice replayed; 2 more to undo, 1 to redo');
expect('replayed by several authors, you and a client id',
  describeUndo([ok(9, [{ author: 'alice', edits: 2 }, { author: '777', edits: 1 }, { author: '123456789', edits: 1 }])], ctx),
  'undone: your stroke #3; 4 later edits replayed (alice 2, you 1, sculptor …6789 1); 2 more to undo, 1 to redo');
expect('redo', describeUndo([ok(9)], { ...ctx, redo: true }), 'redone: your stroke #3; 2 more to undo, 1 to redo');
expect('nothing to undo', describeUndo([refused(E.ERROR_CODE_FAILED_PRECONDITION)], ctx), 'nothing to undo');
expect('nothing to redo', describeUndo([refused(E.ERROR_CODE_FAILED_PRECONDITION)], { ...ctx, redo: true }), 'nothing to redo');
expect('partly undone', describeUndo([ok(9), refused(E.ERROR_CODE_INVALID_ARGUMENT)], ctx),
  'undone: your stroke #3 in part (1 of 2 pieces: cannot undo further: older edits fell off the history); 2 more to undo, 1 to redo');
expect('an older server', describeRefusal({ code: E.ERROR_CODE_MALFORMED }, false), 'this server does not know undo');
expect('a viewer', describeRefusal({ code: E.ERROR_CODE_PERMISSION_DENIED, field: 'Hello.role', value: 'ROLE_VIEWER',
  message: 'viewers may not edit' }, false), 'undo refused: PERMISSION_DENIED Hello.role=ROLE_VIEWER: viewers may not edit');
expect('an edit the page does not know', describeUndo([ok(9)], { ...ctx, drag: 0 }),
  'undone: your last edit; 2 more to undo, 1 to redo');
expect('author names', [authorName('777', '777'), authorName('bob', '777'), authorName('42', '777')],
  ['you', 'bob', 'sculptor …42']);

const key = (k, mods = {}) => undoKey({ key: k, ctrlKey: false, metaKey: false, shiftKey: false, altKey: false, ...mods });
expect('Ctrl+Z undoes', key('z', { ctrlKey: true }), -1);
expect('Cmd+Z undoes', key('z', { metaKey: true }), -1);
expect('Ctrl+Shift+Z redoes (key "Z")', key('Z', { ctrlKey: true, shiftKey: true }), 1);
expect('Cmd+Shift+Z redoes', key('z', { metaKey: true, shiftKey: true }), 1);
expect('Ctrl+Y redoes', key('y', { ctrlKey: true }), 1);
expect('Z alone, Alt+Ctrl+Z and Ctrl+X do nothing',
  [key('z'), key('z', { ctrlKey: true, altKey: true }), key('x', { ctrlKey: true })], [0, 0, 0]);

console.log(failures === 0 ? 'undo tests: all passed' : `undo tests: ${failures} failed`);
process.exit(failures === 0 ? 0 : 1);
