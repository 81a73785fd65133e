#!/usr/bin/env python3
"""Abuse benchmark: a well-behaved sculptor (sculpt-loadgen, 60 Hz, 4 poses a stroke) beside one abusive
client at a time; prints JSON.

For each abuse a fresh sculptd is started; the victim runs alone first (the baseline), then with
the abuser beside it. The abuser speaks the wire protocol directly (protobuf encoded by hand from
proto/sculpt/v1/sculpt.proto, no generated code) from another loopback address (127.0.0.2 by
default), so limits per source address apply to it and not to the victim, as they would to two
hosts.

  tests/bench/abuse_bench.py --bin build/bin [--seconds 10] [--abuses rejoin,set_interest,...]

Abuses: rejoin, set_interest, reconnect, idle, slowloris, heavy (strokes with the largest tool
and the most poses the limits allow), heavy_fit (the heaviest strokes within the stroke-work
limit, 30 a second).

Reported per abuse: the victim's stroke->ack p50/p99/max (ms) and strokes sent/acked/lost with
and without the abuser, the p99 ratio, sculptd's peak and final RSS (MB), its CPU seconds, and the
abuser's own counts (attempts, answers, refusals, connections held).
"""
import argparse
import json
import math
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

# ---- protobuf by hand (proto3 wire format) --------------------------------------------------


def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def f_varint(field, v):
    return varint(field << 3) + varint(v)


def f_bytes(field, b):
    return varint((field << 3) | 2) + varint(len(b)) + b


def f_float(field, v):
    return varint((field << 3) | 5) + struct.pack("<f", v)


def frame(payload):
    return struct.pack("<I", len(payload)) + payload


ROLE_SCULPTOR, ROLE_VIEWER = 1, 2


def hello(token, role, client_id, name="abuser"):
    h = (f_varint(1, 1) + f_bytes(2, token.encode()) + f_varint(3, role) +
         f_bytes(4, name.encode()) + f_varint(5, client_id))
    return frame(f_bytes(1, h))


def join(skip_state):
    return frame(f_bytes(2, f_varint(2, 1) if skip_state else b""))


def subscribe(obj):
    return frame(f_bytes(6, f_bytes(1, obj.encode()) + f_varint(2, 2)))  # LEAF_DELTA


def vec(x, y, z):
    return f_float(1, x) + f_float(2, y) + f_float(3, z)


def set_interest(obj, half):
    box = f_bytes(1, vec(-half, -half, -half)) + f_bytes(2, vec(half, half, half))
    return frame(f_bytes(7, f_bytes(1, obj.encode()) + f_bytes(2, box)))


EDIT_ADD, EDIT_SUBTRACT, TOOL_SPHERE, TOOL_CAPSULE = 2, 3, 1, 4


def stroke(seq, obj, kind, radius, points, tool=TOOL_SPHERE, speed=60.0):
    """A Stroke (ClientMessage field 3): a `tool` of `radius` at `points` (world), the
    poses packed as the codec packs them (int16 offsets at 256 units a voxel from the origin,
    then a uint16 t_ms), 16 ms apart."""
    units_per_world = 256.0 / 0.5  # the built-in scene's voxel_size
    poses = b"".join(
        struct.pack("<hhhH", *(int(round(c * units_per_world)) for c in p), 16 * i)
        for i, p in enumerate(points))
    body = (f_varint(1, seq) + f_bytes(2, obj.encode()) + f_varint(3, kind) +
            f_varint(4, tool) + f_bytes(5, vec(radius, radius, radius)) +
            f_float(6, speed) + f_bytes(8, vec(0.0, 0.0, 0.0)) + f_varint(10, len(points)) +
            f_bytes(11, poses))
    return frame(f_bytes(3, body))


def read_frames(sock, buf):
    """Reads once; returns (frames, buf, closed). Frames are raw ServerMessage payloads."""
    try:
        data = sock.recv(1 << 16)
    except (socket.timeout, BlockingIOError):
        return [], buf, False
    except OSError:
        return [], buf, True
    if not data:
        return [], buf, True
    buf += data
    out = []
    while len(buf) >= 4:
        (n,) = struct.unpack_from("<I", buf)
        if len(buf) < 4 + n:
            break
        out.append(bytes(buf[4:4 + n]))
        buf = buf[4 + n:]
    return out, buf, False


def body_field(payload):
    """The ServerMessage oneof field number of a frame (welcome 1, ack 4, error 6, bye 7...)."""
    i, key = 0, 0
    shift = 0
    while i < len(payload):
        b = payload[i]
        key |= (b & 0x7F) << shift
        i += 1
        if not b & 0x80:
            break
        shift += 7
    return key >> 3


# ---- the abusers ------------------------------------------------------------------------------


class Abuser:
    def __init__(self, port, source, tokens, stop):
        self.port, self.source, self.tokens, self.stop = port, source, tokens, stop
        self.counts = {"attempts": 0, "welcomed": 0, "refused": 0, "errors": 0,
                       "closed_by_server": 0, "bytes_received": 0}
        self.lock = threading.Lock()
        self.held = []

    def count(self, key, n=1):
        with self.lock:
            self.counts[key] = self.counts.get(key, 0) + n

    def connect(self):
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.bind((self.source, 0))
        s.settimeout(2.0)
        s.connect(("127.0.0.1", self.port))
        return s

    def enter(self, role, skip_state, cid):
        """Connects, says Hello and joins; returns the socket or None when refused."""
        try:
            s = self.connect()
            token = self.tokens[0] if role == ROLE_SCULPTOR else self.tokens[1]
            s.sendall(hello(token, role, cid))
            # JoinScene only once the Welcome is in (a join before it is refused).
            buf = b""
            deadline = time.time() + 10
            while True:
                frames, buf, closed = read_frames(s, buf)
                closed = closed or time.time() > deadline
                kinds = [body_field(f) for f in frames]
                if 1 in kinds:
                    self.count("welcomed")
                    break
                if closed or 6 in kinds or 7 in kinds:
                    self.count("refused")
                    s.close()
                    return None
            s.sendall(join(skip_state))
            return s
        except OSError:
            self.count("connect_failures")
            return None

    def drain(self, s, seconds):
        """Reads what comes for up to `seconds`; counts errors, welcomes and a close."""
        buf = b""
        end = time.time() + seconds
        try:
            s.settimeout(0.05)
        except OSError:  # closed by the sender meanwhile
            return False
        while time.time() < end and not self.stop.is_set():
            frames, buf, closed = read_frames(s, buf)
            for f in frames:
                self.count("bytes_received", len(f) + 4)
                k = body_field(f)
                if k == 6:
                    self.count("errors")
                elif k == 4:
                    self.count("acks")
            if closed:
                self.count("closed_by_server")
                return False
        return True

    # A viewer re-joining as fast as it can: connect, Hello, JoinScene with the whole state,
    # hang up without reading.
    def rejoin(self, threads=4):
        def loop(t):
            cid = 1000 + t * 1000000
            while not self.stop.is_set():
                cid += 1
                self.count("attempts")
                s = self.enter(ROLE_VIEWER, False, cid)
                if s:
                    s.close()
        self.run_threads(loop, threads)

    # A replica that moves its interest box as fast as it can (12-byte-ish requests, each
    # answered with the leaves of the region), reading everything.
    def set_interest(self, threads=1):
        def loop(t):
            while not self.stop.is_set():
                s = self.enter(ROLE_VIEWER, True, 5000 + t)
                if not s:
                    time.sleep(0.1)
                    continue
                try:
                    s.sendall(subscribe("clay"))
                    reader = threading.Thread(target=self.drain, args=(s, 1e9), daemon=True)
                    reader.start()
                    i = 0
                    while not self.stop.is_set():
                        s.sendall(set_interest("clay", 30.0 if i % 2 else 8.0))
                        self.count("attempts")
                        i += 1
                except OSError:
                    self.count("closed_by_server")
                finally:
                    s.close()
        self.run_threads(loop, threads)

    # Heavy strokes within every limit: the largest tool the scene allows (a sphere of
    # max_tool_size 16), the longest stroke (max_poses_per_stroke 32, poses 1 world unit apart
    # along the equator, as a drag), adding and taking away in turn (so the object keeps its
    # size), `rate` strokes a second (far below the stroke and pose budgets, 30/s: each such
    # stroke costs the server seconds), acknowledgements read.
    def heavy(self, rate=1.0, radius=16.0, poses=32):
        ring = [(24.0 * math.cos(i / 24.0), 24.0 * math.sin(i / 24.0), 0.0) for i in range(poses)]

        def loop(_):
            seq = 0
            while not self.stop.is_set():
                s = self.enter(ROLE_SCULPTOR, True, 13000 + seq)
                if not s:
                    time.sleep(0.1)
                    continue
                reader = threading.Thread(target=self.drain, args=(s, 1e9), daemon=True)
                reader.start()
                try:
                    next_t = time.time()
                    while not self.stop.is_set():
                        seq += 1
                        kind = EDIT_ADD if seq % 2 else EDIT_SUBTRACT
                        s.sendall(stroke(seq, "clay", kind, radius, ring))
                        self.count("attempts")
                        next_t += 1.0 / rate
                        time.sleep(max(0.0, next_t - time.time()))
                except OSError:
                    self.count("closed_by_server")
                finally:
                    s.close()
        self.run_threads(loop, 1)

    # The heaviest strokes the stroke-work limit lets through (limits.max_stroke_work, default
    # 4 Mi voxel-poses): the largest tool with 4 poses 1 unit apart, adding and taking away in
    # turn, 30 a second (the abuser's whole stroke budget is larger). `heavy` above sends
    # 32-pose strokes, which a server with the limit refuses at once.
    def heavy_fit(self):
        self.heavy(rate=30.0, radius=16.0, poses=4)

    # Reconnect flood: sculptor connections opened, authenticated, joined (no state) and
    # dropped in a loop.
    def reconnect(self, threads=4):
        def loop(t):
            cid = 7000 + t * 1000000
            while not self.stop.is_set():
                cid += 1
                self.count("attempts")
                s = self.enter(ROLE_SCULPTOR, True, cid)
                if s:
                    self.drain(s, 0.02)
                    s.close()
        self.run_threads(loop, threads)

    # Many authenticated viewers that join and then do nothing (but read).
    def idle(self, connections=500):
        def loop(_):
            for i in range(connections):
                if self.stop.is_set():
                    return
                self.count("attempts")
                s = self.enter(ROLE_VIEWER, True, 9000 + i)
                if s:
                    s.setblocking(False)
                    self.held.append(s)
            while not self.stop.is_set():
                alive = []
                for s in self.held:
                    try:
                        data = s.recv(1 << 16)
                        if not data:
                            self.count("closed_by_server")
                            s.close()
                            continue
                    except BlockingIOError:
                        pass
                    except OSError:
                        self.count("closed_by_server")
                        s.close()
                        continue
                    alive.append(s)
                self.held = alive
                self.counts["held_open"] = len(alive)
                time.sleep(0.05)
            for s in self.held:
                s.close()
        self.run_threads(loop, 1)

    # Post-authentication slowloris: joined, then a frame that is never completed, one byte a
    # second.
    def slowloris(self, connections=200):
        def loop(_):
            socks = []
            for i in range(connections):
                if self.stop.is_set():
                    break
                self.count("attempts")
                s = self.enter(ROLE_VIEWER, True, 11000 + i)
                if s:
                    socks.append(s)
            header = struct.pack("<I", 1000)
            k = 0
            while not self.stop.is_set() and socks:
                alive = []
                for s in socks:
                    try:
                        s.sendall(header[k % 4:k % 4 + 1] if k < 4 else b"\x08")
                        alive.append(s)
                    except OSError:
                        self.count("closed_by_server")
                        s.close()
                socks = alive
                self.counts["held_open"] = len(socks)
                k += 1
                time.sleep(1.0)
            for s in socks:
                s.close()
        self.run_threads(loop, 1)

    def run_threads(self, fn, n):
        self.threads = [threading.Thread(target=fn, args=(t,), daemon=True) for t in range(n)]
        for t in self.threads:
            t.start()

    def join_threads(self):
        for t in self.threads:
            t.join(timeout=10)


# ---- the server and the victim -----------------------------------------------------------------


def rss_mb(pid):
    out = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(("VmRSS:", "VmHWM:")):
                    out[line.split(":")[0]] = int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return out


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        rest = f.read().rsplit(")", 1)[1].split()
    return (int(rest[11]) + int(rest[12])) / os.sysconf("SC_CLK_TCK")


class Sculptd:
    def __init__(self, args, tmp):
        self.dir = tempfile.mkdtemp(dir=tmp)
        port_file = os.path.join(self.dir, "port")
        cmd = [args.sculptd or os.path.join(args.bin, "sculptd"), "serve", "--listen", "127.0.0.1:0", "--http",
               "off", "--data", os.path.join(self.dir, "data"), "--port-file", port_file]
        if args.config:
            cmd += ["--config", args.config]
        cmd += args.server_arg or []
        if args.server_cpus:
            cmd = ["taskset", "-c", args.server_cpus] + cmd
        self.log = open(os.path.join(self.dir, "sculptd.log"), "w")
        self.proc = subprocess.Popen(cmd, stdout=self.log, stderr=subprocess.STDOUT)
        for _ in range(1000):
            try:
                with open(port_file) as f:
                    self.port = int(f.readline())
                    break
            except (OSError, ValueError):
                time.sleep(0.01)
        else:
            raise RuntimeError("sculptd did not start: " + self.dir)

    def stop(self, keep_log=None):
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.log.close()
        lines = sum(1 for _ in open(self.log.name, errors="replace"))
        if keep_log:
            shutil.copy(self.log.name, keep_log)
        shutil.rmtree(self.dir, ignore_errors=True)
        return lines


def victim(args, port):
    cmd = [args.loadgen or os.path.join(args.bin, "sculpt-loadgen"), "--server", f"127.0.0.1:{port}",
           "--sculptors", "1", "--rate", str(args.hz), "--poses-per-stroke",
           str(args.poses_per_stroke), "--replay-replicas", "0", "--leafdelta-replicas", "0",
           "--seconds", str(args.seconds), "--drain-seconds", "5", "--json"]
    if args.client_cpus:
        cmd = ["taskset", "-c", args.client_cpus] + cmd
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=args.seconds + 120)
    if out.returncode != 0:
        return {"failed": (out.stdout + out.stderr)[-2000:], "returncode": out.returncode}
    r = json.loads(out.stdout)
    keep = ["strokes_sent", "strokes_acked", "strokes_refused", "strokes_unacked",
            "stroke_ack_p50_ms", "stroke_ack_p99_ms", "stroke_ack_max_ms", "server_errors"]
    return {k: r.get(k) for k in keep}


def run_one(args, name):
    d = Sculptd(args, args.tmp)
    try:
        base = victim(args, d.port)
        stop = threading.Event()
        ab = Abuser(d.port, args.source, (args.sculptor_token, args.viewer_token), stop)
        cpu0 = cpu_seconds(d.proc.pid)
        getattr(ab, name)()
        peak = {"VmRSS": 0.0}
        watching = threading.Event()

        def watch():
            while not watching.is_set():
                r = rss_mb(d.proc.pid).get("VmRSS", 0.0)
                peak["VmRSS"] = max(peak["VmRSS"], r)
                time.sleep(0.1)
        w = threading.Thread(target=watch, daemon=True)
        w.start()
        time.sleep(1.0)  # the abuse is under way before the victim starts
        under = victim(args, d.port)
        stop.set()
        ab.join_threads()
        watching.set()
        w.join()
        cpu = cpu_seconds(d.proc.pid) - cpu0
        rss = rss_mb(d.proc.pid)
        lines = d.stop(args.keep_log)
        b99, u99 = base.get("stroke_ack_p99_ms"), under.get("stroke_ack_p99_ms")
        return {
            "abuse": name,
            "victim_alone": base,
            "victim_with_abuser": under,
            "p99_ratio": round(u99 / b99, 2) if b99 and u99 is not None else None,
            "strokes_lost": (under.get("strokes_sent", 0) or 0) - (under.get("strokes_acked", 0) or 0),
            "server_rss_peak_mb": round(peak["VmRSS"], 1),
            "server_rss_end_mb": round(rss.get("VmRSS", 0.0), 1),
            "server_cpu_s_during_abuse": round(cpu, 2),
            "server_log_lines": lines,
            "abuser": ab.counts,
        }
    except BaseException:
        d.stop()
        raise


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bin", default="build/bin", help="folder of sculptd and sculpt-loadgen")
    p.add_argument("--sculptd", help="sculptd binary (default: BIN/sculptd)")
    p.add_argument("--loadgen", help="sculpt-loadgen binary (default: BIN/sculpt-loadgen)")
    p.add_argument("--seconds", type=float, default=10, help="victim's sending phase, each run")
    p.add_argument("--hz", type=int, default=60, help="victim's pose samples per second")
    p.add_argument("--poses-per-stroke", type=int, default=4, help="victim's poses per stroke")
    p.add_argument("--abuses", default="rejoin,set_interest,reconnect,idle,slowloris,heavy")
    p.add_argument("--source", default="127.0.0.2", help="abuser's source address")
    p.add_argument("--config", help="sculptd --config file (default: the built-in scene)")
    p.add_argument("--server-arg", action="append", help="extra sculptd serve argument")
    p.add_argument("--sculptor-token", default="sculpt-dev-sculptor")
    p.add_argument("--viewer-token", default="sculpt-dev-viewer")
    p.add_argument("--server-cpus", help="taskset -c list for sculptd (e.g. 0)")
    p.add_argument("--client-cpus", help="taskset -c list for the victim and the abuser (e.g. 1)")
    p.add_argument("--keep-log", help="copy sculptd's log of the last run here")
    p.add_argument("--tmp", default=tempfile.gettempdir())
    args = p.parse_args()
    if args.client_cpus:  # the abuser is this process
        os.sched_setaffinity(0, {int(c) for c in args.client_cpus.split(",")})
    results = {"seconds": args.seconds, "victim_hz": args.hz, "source": args.source,
               "sculptd": os.path.abspath(args.sculptd or os.path.join(args.bin, "sculptd")), "runs": []}
    for name in args.abuses.split(","):
        print(f"abuse {name}...", file=sys.stderr)
        results["runs"].append(run_one(args, name))
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
