// The web client's outbox (client/web/src/connection.js, Outbox) in node, without a browser or a
// server: unanswered requests are kept, resent in order after a reconnection (also the ones made
// while it was held), and sent at the pace given, so a resend burst stays under the server's
// per-client rate limits. Needs the generated protobuf code (client/web/gen). Usage:
//   node test/outbox_test.mjs
import { Outbox } from '../src/connection.js';

let failures = 0;
function expect(name, got, want) {
  const ok = JSON.stringify(got) === JSON.stringify(want);
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}${ok ? '' : `: got ${JSON.stringify(got)}, want ${JSON.stringify(want)}`}`);
  if (!ok) failures += 1;
}

// A wire that records what is written, and a clock the test moves (drain's own timers find the
// clock unmoved and send nothing more).
function rig(rate = { strokesPerSecond: 10, strokeBurst: 3, posesPerSecond: 1000, poseBurst: 1000 }) {
  const t = { now: 0, wire: [], up: true };
  t.box = new Outbox((body, value) => {
    if (!t.up) return false;
    t.wire.push(`${body}${value.clientSeq}`);
    return true;
  }, rate, () => t.now);
  t.later = (ms) => { t.now += ms; t.box.drain(); };
  return t;
}
const stroke = (seq) => ({ clientSeq: seq });

{
  const t = rig();
  t.box.open = true;
  for (let s = 1; s <= 5; ++s) t.box.add('stroke', stroke(s), 1);
  expect('a burst goes out at once, the rest waits', t.wire, ['stroke1', 'stroke2', 'stroke3']);
  t.later(100);
  expect('one more a tenth of a second later at 10/s', t.wire, ['stroke1', 'stroke2', 'stroke3', 'stroke4']);
  t.later(100);
  expect('in order', t.wire.slice(-1), ['stroke5']);
  clearTimeout(t.box.timer);
}

{
  const t = rig({ strokesPerSecond: 1000, strokeBurst: 1000, posesPerSecond: 100, poseBurst: 40 });
  t.box.open = true;
  t.box.add('stroke', stroke(1), 32);
  t.box.add('stroke', stroke(2), 32);
  expect('poses bound the pace too', t.wire, ['stroke1']);
  t.later(200);
  expect('the next stroke once its poses are there', t.wire, ['stroke1']);
  t.later(100);
  expect('…after 240 ms at 100 poses/s', t.wire, ['stroke1', 'stroke2']);
}

{
  const t = rig({ strokesPerSecond: 1000, strokeBurst: 1000, posesPerSecond: 1e6, poseBurst: 1e6 });
  t.box.open = true;
  t.box.add('stroke', stroke(1), 2);
  t.box.add('paint', stroke(2));
  t.box.add('stroke', stroke(3), 2);
  t.box.add('undo', stroke(4));
  t.box.settle(1);
  t.box.settle(4);  // answered out of order: 2 and 3 are still unanswered
  t.box.hold();
  t.box.add('stroke', stroke(5), 2);  // made while reconnecting
  expect('nothing goes out while held', t.wire.length, 4);
  t.wire.length = 0;
  const resent = t.box.resume();
  expect('every unanswered request again, oldest first, then the new one', t.wire, ['paint2', 'stroke3', 'stroke5']);
  expect('resent counts the ones written before', resent, 2);
  expect('kept until answered', t.box.size, 3);
  let empty = 0;
  t.box.onEmpty = () => { empty += 1; };
  for (const s of [2, 3, 5]) t.box.settle(s);
  expect('empty once all are answered', [t.box.size, empty], [0, 1]);
}

{
  const t = rig({ strokesPerSecond: 1000, strokeBurst: 1000, posesPerSecond: 1e6, poseBurst: 1e6 });
  t.box.open = true;
  t.up = false;
  t.box.add('stroke', stroke(1), 1);
  t.box.add('stroke', stroke(2), 1);
  expect('a closed socket writes nothing and stops the drain', [t.wire.length, t.box.open], [0, false]);
  t.up = true;
  expect('written after the reconnection, not counted as resent', [t.box.resume(), t.wire], [0, ['stroke1', 'stroke2']]);
}

{
  // JoinScene.resends: one range per stream over the unanswered requests, oldest first, all
  // ranges within the bound (a stream's range counts the other streams' sequences it spans).
  const t = rig();
  t.box.add('stroke', stroke(3), 1);
  t.box.add('paint', stroke(4));
  t.box.add('stroke', stroke(5), 1);
  t.box.add('undo', stroke(6));
  t.box.add('stroke', stroke(7), 1);
  const S = 1, P = 2, U = 6;  // EditStream values
  expect('ranges of every unanswered request', t.box.resendRanges(100), [
    { stream: S, firstSeq: 3, lastSeq: 7 }, { stream: P, firstSeq: 4, lastSeq: 4 },
    { stream: U, firstSeq: 6, lastSeq: 6 }]);
  expect('bounded: stops at the first request past the bound', t.box.resendRanges(4), [
    { stream: S, firstSeq: 3, lastSeq: 5 }, { stream: P, firstSeq: 4, lastSeq: 4 }]);
  expect('nothing with a bound of 0', t.box.resendRanges(0), []);
  t.box.settle(3);
  expect('answered ones are not declared', t.box.resendRanges(100).find((r) => r.stream === S),
    { stream: S, firstSeq: 5, lastSeq: 7 });
}

console.log(failures === 0 ? 'outbox test: all passed' : `outbox test: ${failures} failed`);
process.exit(failures === 0 ? 0 : 1);
