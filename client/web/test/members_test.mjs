// The web client's list of cluster members to rejoin through (client/web/src/connection.js,
// clusterHttpAddresses) in node, without a browser or a server: SceneInfo.cluster_members as
// decoded from the wire gives the members' HTTP addresses, in order, without duplicates, at most
// 64, and anything that is not HOST:PORT is skipped. Needs the generated protobuf code
// (client/web/gen). Usage:
//   node test/members_test.mjs
import { clusterHttpAddresses, isHostPort, kMaxClusterMembers, v1 } from '../src/connection.js';

let failures = 0;
function expect(name, got, want) {
  const ok = JSON.stringify(got) === JSON.stringify(want);
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}${ok ? '' : `: got ${JSON.stringify(got)}, want ${JSON.stringify(want)}`}`);
  if (!ok) failures += 1;
}

// Through the wire: what a member sends is what the page reads.
function decoded(members) {
  const bytes = v1.ServerMessage.encode(v1.ServerMessage.create({
    sceneInfo: { scene: 'default', clusterMembers: members } })).finish();
  return v1.ServerMessage.decode(bytes).sceneInfo;
}

expect('a single process lists none', clusterHttpAddresses(decoded([])), []);
expect('no SceneInfo, none', clusterHttpAddresses(undefined), []);
expect('the members in order', clusterHttpAddresses(decoded([
  { name: 'a', tcpAddress: '127.0.0.1:7001', httpAddress: '127.0.0.1:8001' },
  { name: 'b', tcpAddress: '127.0.0.1:7002', httpAddress: '127.0.0.1:8002' },
  { name: 'c', tcpAddress: 'sculpt-2.sculpt:7000', httpAddress: 'sculpt-2.sculpt:8080' },
  { name: 'd', tcpAddress: '[::1]:7004', httpAddress: '[::1]:8004' },
])), ['127.0.0.1:8001', '127.0.0.1:8002', 'sculpt-2.sculpt:8080', '[::1]:8004']);
expect('a member without an HTTP port and duplicates are skipped', clusterHttpAddresses(decoded([
  { name: 'a', tcpAddress: '127.0.0.1:7001', httpAddress: '' },
  { name: 'b', tcpAddress: '127.0.0.1:7002', httpAddress: '127.0.0.1:8002' },
  { name: 'b2', tcpAddress: '127.0.0.1:7003', httpAddress: '127.0.0.1:8002' },
])), ['127.0.0.1:8002']);
const bad = ['127.0.0.1', '127.0.0.1:0', '127.0.0.1:65536', 'http://127.0.0.1:8001', '127.0.0.1:80/ws',
  'evil.example:80@x', ':8080', 'a b:80', '[::1:80', `${'a'.repeat(300)}:80`, '-x:80', 'x:80#frag'];
expect('not HOST:PORT', bad.filter(isHostPort), []);
expect('forged entries are skipped', clusterHttpAddresses(decoded(bad.map((h, i) => (
  { name: `m${i}`, httpAddress: h })))), []);
expect('HOST:PORT', ['localhost:1', 'h:65535', '10.0.0.1:8080', '[fe80::1]:443'].filter(isHostPort),
  ['localhost:1', 'h:65535', '10.0.0.1:8080', '[fe80::1]:443']);
const many = [];
for (let i = 0; i < 100; ++i) many.push({ name: `m${i}`, httpAddress: `127.0.0.1:${9000 + i}` });
const kept = clusterHttpAddresses(decoded(many));
expect('at most 64 kept', [kept.length, kMaxClusterMembers, kept[0], kept[63]],
  [64, 64, '127.0.0.1:9000', '127.0.0.1:9063']);

if (failures > 0) {
  console.error(`${failures} check(s) failed`);
  process.exit(1);
}
console.log('all checks passed');
