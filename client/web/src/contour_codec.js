// The contour codec's decoder (common/include/sculpt/skin/contour_codec.h): polyline sets, skin
// snapshots and skin updates, in SKC4's and SKC3's turtle coding (SKC4: SKC3 with the chord
// rule predicting each chord) (integers as whole symbols from static
// rANS tables, placed by a turtle on a hexagonal lattice), SKC2's curve coding (an adaptive
// binary range coder over residuals of a circle-continuing prediction; in both, every double
// operation repeats the C++ one, so both decode the same points to the bit) and SKC1's two
// residual codings (varints, and
// Draco's rANS symbol coding as draco::EncodeSymbols writes it, tagged or raw scheme). Plain ES
// module, no dependencies: bundled into the web client and run by node in the tests.
//
// Bytes come off the wire: every read is bounded, counts are capped as the C++ decoder caps
// them, and anything wrong throws a ContourError naming it. Every message the C++ decoder
// refuses is refused here; a few it accepts are refused too, all of which no encoder writes:
// - Draco's tagged scheme reads value bits past the end of the message as zeros, so a message
//   cut inside its values decodes, wrongly, in C++; here it is "truncated";
// - a rANS stream must end in the state it started from, having used all its bytes (Draco's
//   decoder has ans.read_end() but ignores it), which catches most corrupted symbol data;
// - a rANS stream whose final-state tag claims 4 bytes must have them (Draco reads up to 3 bytes
//   before the stream);
// - section ids and versions must be below 2^53 (JavaScript numbers).

/** Thrown for truncated, oversized or malformed input; the message names what is wrong. */
export class ContourError extends Error {
  constructor(message) {
    super(message);
    this.name = 'ContourError';
  }
}

/** Upper bounds on untrusted input, as skin::kMaxContourPoints / kMaxContourPolylines. */
export const kMaxContourPoints = 2 ** 26;
export const kMaxContourPolylines = 2 ** 24;

const kMagic = [0x53, 0x4b, 0x43];  // "SKC", then '1' or '2'
const kPolylineSet = 0;
const kSnapshot = 1;
const kUpdate = 2;
const kVarint = 0;
const kRans = 1;
const kCurve = 2;
const kMaxQuantised = 2 ** 52;
const kExact = 2 ** 53;  // integers up to here are exact doubles
const kPow2 = Float64Array.from({ length: 54 }, (_, i) => 2 ** i);

function truncated(what) {
  return new ContourError(`contour: truncated ${what}`);
}

// ---------------------------------------------------------------------------------------------
// Integers. A decoded value is a Number when below 2^53 (exact) and a BigInt above, so that a
// hostile 64-bit value is neither rounded nor mistaken for a small one.

/** Unsigned LEB128 of at most `maxBytes` bytes, reduced modulo 2^`bits`; null if cut short. */
function readVarint(bytes, pos, end, maxBytes, bits) {
  let v = 0;
  let n = 0;
  for (;;) {
    if (n === maxBytes || pos + n >= end) return null;
    const b = bytes[pos + n];
    n += 1;
    if (!(b & 0x80)) break;
  }
  if (n <= 7) {  // at most 49 bits: exact as a Number
    for (let i = n - 1; i >= 0; --i) v = v * 128 + (bytes[pos + i] & 0x7f);
    if (bits < 49) v %= 2 ** bits;
    return { value: v, size: n };
  }
  let big = 0n;
  for (let i = n - 1; i >= 0; --i) big = (big << 7n) | BigInt(bytes[pos + i] & 0x7f);
  big = BigInt.asUintN(bits, big);
  return { value: big < BigInt(kExact) ? Number(big) : big, size: n };
}

/** Zigzag back to a signed value (Number in, Number out; BigInt in, BigInt out). */
function unzig(u) {
  if (typeof u === 'bigint') return (u >> 1n) ^ -(u & 1n);
  return u % 2 === 0 ? u / 2 : -(u + 1) / 2;
}

/** Exact a + b of two integers (Numbers or BigInts); a Number when |a + b| <= 2^53. */
function addExact(a, b) {
  if (typeof a === 'number' && typeof b === 'number') {
    const s = a + b;  // exact whenever the true sum is at most 2^53 in magnitude
    if (Math.abs(s) <= kExact) return s;
  }
  const s = BigInt(a) + BigInt(b);
  return s >= -BigInt(kExact) && s <= BigInt(kExact) ? Number(s) : s;
}

/** llround: to the nearest integer, halves away from zero. */
function roundAway(z) {
  return z < 0 ? -Math.round(-z) : Math.round(z);
}

// ---------------------------------------------------------------------------------------------
// Draco's entropy decoding (draco/compression/entropy: symbol_decoding.cc, rans_symbol_decoder.h,
// ans.h), for the bitstream version >= 2.0 layout (varint sizes), which is what the C++ decoder
// asks for. A failure throws with the reason; the C++ side only says "do not decode".

/** A position in the message shared by the symbol decoders (DecoderBuffer). */
class DracoBuffer {
  constructor(bytes, pos, end) {
    this.bytes = bytes;
    this.pos = pos;
    this.end = end;
  }
  remaining() {
    return this.end - this.pos;
  }
  byte(what) {
    if (this.pos >= this.end) throw symbolError(`truncated ${what}`);
    return this.bytes[this.pos++];
  }
  /** DecodeVarint<uint32_t> (at most 5 bytes) or <uint64_t> (at most 10). */
  varint(bits, what) {
    const r = readVarint(this.bytes, this.pos, this.end, bits === 32 ? 5 : 10, bits);
    if (!r) throw symbolError(`truncated or overlong ${what}`);
    this.pos += r.size;
    return r.value;
  }
}

function symbolError(why) {
  return new ContourError(`contour: residual symbols do not decode (${why})`);
}

/** ComputeRAnsPrecisionFromUniqueSymbolsBitLength: 3/2 of the bit length, clamped to [12, 20]. */
function ransPrecisionBits(uniqueSymbolsBitLength) {
  const p = Math.floor((3 * uniqueSymbolsBitLength) / 2);
  return p < 12 ? 12 : p > 20 ? 20 : p;
}

/** RAnsSymbolDecoder: a probability table, then a rANS stream decoded back to front. */
class RansSymbolDecoder {
  constructor(precisionBits) {
    this.precisionBits = precisionBits;
    this.precision = 2 ** precisionBits;
    this.base = 4 * this.precision;  // l_rans_base: the state stays in [base, base * 256)
    this.numSymbols = 0;
  }

  /** Create(): the symbol count and each symbol's probability, which must sum to precision. */
  readTable(buf) {
    const n = buf.varint(32, 'rANS symbol count');
    // A table entry is at least a byte per 64 symbols (runs of zero probabilities).
    if (Math.floor(n / 64) > buf.remaining()) {
      throw symbolError(`rANS symbol count ${n} for ${buf.remaining()} bytes`);
    }
    this.numSymbols = n;
    if (n === 0) return;
    const prob = new Uint32Array(n);
    for (let i = 0; i < n; ++i) {
      const first = buf.byte('rANS probability table');
      const token = first & 3;
      if (token === 3) {  // a run of offset + 1 zero probabilities
        const offset = first >> 2;
        if (i + offset >= n) throw symbolError(`rANS zero run past symbol ${n}`);
        i += offset;
      } else {  // 6 bits here, then `token` more bytes
        let p = first >> 2;
        for (let b = 0; b < token; ++b) p += buf.byte('rANS probability table') * 2 ** (8 * b + 6);
        prob[i] = p;
      }
    }
    this.prob = prob;
    this.cum = new Uint32Array(n);
    this.lookup = new Uint32Array(this.precision);
    let cum = 0;
    for (let i = 0; i < n; ++i) {
      this.cum[i] = cum;
      const next = cum + prob[i];
      if (next > this.precision) {
        throw symbolError(`rANS probabilities exceed the precision ${this.precision}`);
      }
      this.lookup.fill(i, cum, next);
      cum = next;
    }
    if (cum !== this.precision) {
      throw symbolError(`rANS probabilities sum to ${cum}, not the precision ${this.precision}`);
    }
  }

  /** StartDecoding(): the stream's size, then its final state from its last 1 to 4 bytes. */
  start(buf) {
    const size = buf.varint(64, 'rANS stream size');
    if (typeof size === 'bigint' || size > buf.remaining()) {
      throw symbolError(`rANS stream of ${size} bytes with ${buf.remaining()} left`);
    }
    const head = buf.pos;
    buf.pos += size;
    if (size < 1) throw symbolError('empty rANS stream');
    const b = buf.bytes;
    const last = head + size - 1;
    const x = b[last] >> 6;
    let state;
    if (x === 0) {
      this.offset = size - 1;
      state = b[last] & 0x3f;
    } else if (x === 1) {
      if (size < 2) throw symbolError('rANS state cut short');
      this.offset = size - 2;
      state = (b[last - 1] | (b[last] << 8)) & 0x3fff;
    } else if (x === 2) {
      if (size < 3) throw symbolError('rANS state cut short');
      this.offset = size - 3;
      state = (b[last - 2] | (b[last - 1] << 8) | (b[last] << 16)) & 0x3fffff;
    } else {
      if (size < 4) throw symbolError('rANS state cut short');  // unchecked in Draco
      this.offset = size - 4;
      state = (b[last - 3] + b[last - 2] * 2 ** 8 + b[last - 1] * 2 ** 16 + b[last] * 2 ** 24) %
              2 ** 30;
    }
    state += this.base;
    if (state >= this.base * 256) throw symbolError('rANS initial state out of range');
    this.state = state;
    this.head = head;
    this.bytes = b;
  }

  /** The encoder starts from the base state: after the last symbol (and the refill that
   *  undoes the encoder's first renormalisation) the decoder must be back there, every byte
   *  used. */
  end() {
    let s = this.state;
    while (s < this.base && this.offset > 0) s = s * 256 + this.bytes[this.head + --this.offset];
    if (s !== this.base || this.offset !== 0) {
      throw symbolError('rANS stream does not end in its initial state (corrupted)');
    }
  }

  /** rans_read(): refill from the back while below base (never before the stream's start). */
  next() {
    // The state stays below base * 256 <= 2^30: int32 arithmetic throughout.
    let s = this.state;
    while (s < this.base && this.offset > 0) s = (s << 8) | this.bytes[this.head + --this.offset];
    const rem = s & (this.precision - 1);
    const quo = s >>> this.precisionBits;
    const sym = this.lookup[rem];
    this.state = quo * this.prob[sym] + rem - this.cum[sym];
    return sym;
  }
}

/**
 * draco::DecodeSymbols(numValues, numComponents, buffer, out): a scheme byte, then the tagged
 * scheme (rANS-coded bit lengths per group of numComponents values, the values as raw
 * least-significant-bit-first bits after the rANS data) or the raw scheme (each value a rANS
 * symbol, the precision from a bit-length byte). Advances buf.pos as Draco does.
 */
function decodeSymbols(numValues, numComponents, buf, out) {
  if (numValues === 0) return { scheme: null };
  const scheme = buf.byte('symbol scheme');
  if (scheme === 0) {
    const tags = new RansSymbolDecoder(ransPrecisionBits(5));
    tags.readTable(buf);
    tags.start(buf);
    if (tags.numSymbols === 0) throw symbolError('tagged scheme without tags');
    // The values' bits follow the tags' rANS data, least significant first. Draco reads bits
    // past the end as zeros; a valid message never needs them, so here they mean truncation.
    const b = buf.bytes;
    const start = buf.pos;
    const availBits = (buf.end - start) * 8;
    let bit = 0;
    let id = 0;
    for (let i = 0; i < numValues; i += numComponents) {
      const length = tags.next();
      if (length > 32) throw symbolError(`tagged bit length ${length} above 32`);
      if (bit + numComponents * length > availBits) {
        throw truncated('residuals (tagged values past the end of the message)');
      }
      for (let j = 0; j < numComponents; ++j) {
        let v = 0;
        for (let got = 0; got < length;) {  // up to a byte at a time
          const shift = bit & 7;
          const take = Math.min(8 - shift, length - got);
          v += ((b[start + (bit >> 3)] >> shift) & ((1 << take) - 1)) * kPow2[got];
          got += take;
          bit += take;
        }
        out[id++] = v;
      }
    }
    tags.end();
    buf.pos = start + Math.ceil(bit / 8);
    return { scheme: 'tagged', precisionBits: tags.precisionBits };
  }
  if (scheme === 1) {
    const bitLength = buf.byte('raw scheme bit length');
    if (bitLength < 1 || bitLength > 18) {
      throw symbolError(`raw scheme bit length ${bitLength} outside [1, 18]`);
    }
    const dec = new RansSymbolDecoder(ransPrecisionBits(bitLength));
    dec.readTable(buf);
    if (dec.numSymbols === 0) throw symbolError('raw scheme without symbols');
    dec.start(buf);
    for (let i = 0; i < numValues; ++i) out[i] = dec.next();
    dec.end();
    return { scheme: 'raw', precisionBits: dec.precisionBits, bitLength };
  }
  throw symbolError(`scheme ${scheme} outside [0, 1]`);
}

// ---------------------------------------------------------------------------------------------
// SKC2's curve coding (CurveBody / DecodeCurveBody in contour_codec.cc, the range coder in
// common/src/skin/range_coder.cc).

const kProbBits = 12;
const kOne = 1 << kProbBits;
const kAdapt = 5;
const kTop = 2 ** 24;
const kMaxIntBucket = 52;
const kMaxExactId = 2 ** 53 - 1;
const kRatioLo = 0.95;
const kRatioHi = 1 / 0.95;
const kAlongContexts = 6;
const kAcrossContexts = 10;

/** RangeDecoder: LZMA's binary range decoding with 12-bit adaptive probabilities. Reads past
 *  the end see zeros and are counted; all state stays below 2^32 (exact in doubles). */
class RangeDecoder {
  constructor(bytes, pos, end) {
    this.bytes = bytes;
    this.pos = pos;
    this.start = pos;
    this.end = end;
    this.overrun = 0;
    this.range = 0xffffffff;
    this.code = 0;
    this.firstOk = this.next() === 0;
    for (let i = 0; i < 4; ++i) this.code = this.code * 256 + this.next();
  }
  next() {
    if (this.pos >= this.end) {
      this.overrun += 1;
      return 0;
    }
    return this.bytes[this.pos++];
  }
  ok() {
    return this.firstOk && this.overrun === 0;
  }
  consumed() {
    return this.pos - this.start;
  }
  normalize() {
    while (this.range < kTop) {
      this.range = (this.range * 256) >>> 0;
      // code < range in a valid stream; a corrupt one wraps modulo 2^32 as uint32 would.
      this.code = (this.code * 256 + this.next()) >>> 0;
    }
  }
  /** A bit with the adaptive probability models[i] (of a 0, in 1/4096). */
  bit(models, i) {
    const p = models[i];
    const bound = (this.range >>> kProbBits) * p;
    let b;
    if (this.code < bound) {
      this.range = bound;
      models[i] = p + ((kOne - p) >> kAdapt);
      b = 0;
    } else {
      this.code -= bound;
      this.range -= bound;
      models[i] = p - (p >> kAdapt);
      b = 1;
    }
    this.normalize();
    return b;
  }
  /** `count` bits at probability 1/2, most significant first (count <= 51: exact). */
  raw(count) {
    let v = 0;
    for (let i = 0; i < count; ++i) {
      this.range >>>= 1;
      let b = 0;
      if (this.code >= this.range) {
        this.code -= this.range;
        b = 1;
      }
      v = v * 2 + b;
      this.normalize();
    }
    return v;
  }
  /**
   * A signed integer (IntModel: zero, sign, 52 length models, 53 top-bit models), |v| < 2^53.
   * The same decisions as bit() and raw() in one loop, the decoder's state in locals: about
   * eleven decisions a point, and a field is a memory access where a local is a register.
   */
  int(m) {
    const bytes = this.bytes;
    const end = this.end;
    let range = this.range;
    let code = this.code;
    let pos = this.pos;
    let overrun = this.overrun;
    // The model of the next decision: 0 zero, 1 sign, 2 + k length, 2 + kMaxIntBucket + k top.
    let i = 0;
    let negative = false;
    let k = 0;
    let mag = 0;
    for (;;) {
      const p = m[i];
      const bound = (range >>> kProbBits) * p;
      let b = 0;
      if (code < bound) {
        range = bound;
        m[i] = p + ((kOne - p) >> kAdapt);
      } else {
        code -= bound;
        range -= bound;
        m[i] = p - (p >> kAdapt);
        b = 1;
      }
      while (range < kTop) {
        range = (range * 256) >>> 0;
        let byte = 0;
        if (pos < end) byte = bytes[pos++];
        else overrun += 1;
        code = (code * 256 + byte) >>> 0;
      }
      if (i === 0) {
        if (b === 0) break;
        i = 1;
      } else if (i === 1) {
        negative = b === 1;
        i = 2;
      } else if (i < 2 + kMaxIntBucket) {
        if (b === 1) ++k;
        if (b === 1 && k < kMaxIntBucket) {
          i = 2 + k;
        } else if (k === 0) {
          mag = 1;
          break;
        } else {
          i = 2 + kMaxIntBucket + k;
        }
      } else {
        mag = (2 + b) * kPow2[k - 1];
        let v = 0;
        for (let j = 1; j < k; ++j) {
          range >>>= 1;
          let r = 0;
          if (code >= range) {
            code -= range;
            r = 1;
          }
          v = v * 2 + r;
          while (range < kTop) {
            range = (range * 256) >>> 0;
            let byte = 0;
            if (pos < end) byte = bytes[pos++];
            else overrun += 1;
            code = (code * 256 + byte) >>> 0;
          }
        }
        mag += v;
        break;
      }
    }
    this.range = range;
    this.code = code;
    this.pos = pos;
    this.overrun = overrun;
    return negative ? -mag : mag;
  }
}

/** An IntModel's probabilities: zero, sign, length[52], top[53]. */
function intModel() {
  return new Uint16Array(2 + kMaxIntBucket + kMaxIntBucket + 1).fill(kOne / 2);
}

/** std::clamp(v, lo, hi) (NaN passes through). */
function clamp(v, lo, hi) {
  return v < lo ? lo : hi < v ? hi : v;
}

function alongContext(k, prev) {
  if (k === 1) return 5;
  const m = Math.abs(prev);
  return m === 0 ? 0 : m <= 2 ? 1 : m <= 8 ? 2 : m <= 32 ? 3 : 4;
}

function acrossContext(k, prevE, a) {
  if (k === 1) return 9;
  return Math.min(Math.abs(prevE), 2) + 3 * Math.min(Math.abs(a), 2);
}

/**
 * Decodes the curve coding's body, bytes[pos..], into p: the section entries (index, id,
 * version) of a skin message, then every line's point count (capped by the message size), then
 * the points. Throws ContourError as DecodeCurveBody returns its errors.
 */
function decodeCurveBody(bytes, pos, p, nentries, nlines) {
  const rc = new RangeDecoder(bytes, pos, bytes.length);
  const step = p.step;
  const kind = p.kind;
  const m = {
    index: intModel(), id: intModel(), version: intModel(), count: intModel(),
    first: intModel(), join: new Uint16Array(1).fill(kOne / 2),
    closed: new Uint16Array(1).fill(kOne / 2),
    along: Array.from({ length: kAlongContexts }, intModel),
    across: Array.from({ length: kAcrossContexts }, intModel),
  };
  const stride = kind === kPolylineSet ? 1 : 2;
  let index = -1;
  let id = -1;
  let version = 0;
  for (let e = 0; e < nentries; ++e) {
    index = kind === kUpdate ? index + 1 + rc.int(m.index) : index + 1;
    id = id + 1 + rc.int(m.id);
    version += rc.int(m.version);
    if (!rc.ok()) throw truncated('section entries');
    if (index < 0 || index >= p.sectionCount) {
      throw new ContourError(`contour.section_index=${index} outside [0, ${p.sectionCount})`);
    }
    if (id < 0 || id > kMaxExactId || version < 0 || version > kMaxExactId) {
      throw new ContourError(`contour.section_id/version=${id}/${version} outside [0, 2^53)`);
    }
    p.index.push(index);
    p.id.push(id);
    p.version.push(version);
  }
  const counts = [];
  let total = 0;
  const cap = Math.min(kMaxContourPoints, 65536 + 512 * bytes.length);
  for (let j = 0; j < nlines; ++j) {
    const prev = j >= stride ? counts[j - stride] : 0;
    const n = prev + rc.int(m.count);
    if (!rc.ok()) throw truncated('point counts');
    if (n < 0) throw new ContourError(`contour.points=${n} for a polyline`);
    total += n;
    if (n > cap || total > cap) {
      throw new ContourError(`contour.points=${total} outside [0, ${cap}] for a ` +
                             `${bytes.length}-byte message`);
    }
    counts.push(n);
  }
  const limit = kMaxQuantised * step;
  const tail = new Float64Array(6);
  const outside = () => new ContourError('contour: decoded point outside [-2^52, 2^52] steps');
  // The lines are views into a few large blocks: one typed array per line costs more than
  // decoding its points. A block holds what is left of the claimed total, at most 2^16 points, so
  // a count that lies still allocates only as the points arrive.
  let block = null;
  let blockAt = 0;
  let left = total;
  let l1 = -1;  // the last frame's step length (MakeFrame's l2_known)
  for (let j = 0; j < nlines; ++j) {
    const n = counts[j];
    if (2 * n > (block ? block.length - blockAt : 0)) {
      block = allocate(Float64Array, 2 * Math.max(n, Math.min(left, 1 << 16)));
      blockAt = 0;
    }
    const out = block ? block.subarray(blockAt, blockAt + 2 * n) : new Float64Array(0);
    blockAt += 2 * n;
    left -= n;
    p.lines.push(out);
    if (n === 0) continue;
    const ctx = j >= stride ? p.lines[j - stride] : null;
    // The tail: the last three decoded points, oldest first (have of them valid).
    let have = 0;
    if (ctx && ctx.length && rc.bit(m.join, 0)) {
      const from = Math.max(0, ctx.length / 2 - 3);
      have = ctx.length / 2 - from;
      tail.set(ctx.subarray(2 * from), 6 - 2 * have);
    }
    if (have === 0) {
      let rx = 0;
      let ry = 0;
      if (ctx && ctx.length) {
        rx = roundAway(ctx[ctx.length - 2] / step);
        ry = roundAway(ctx[ctx.length - 1] / step);
      }
      const x = rx + rc.int(m.first);
      const y = ry + rc.int(m.first);
      if (Math.abs(x) > kMaxQuantised || Math.abs(y) > kMaxQuantised) throw outside();
      tail[4] = x * step;
      tail[5] = y * step;
      have = 1;
    }
    out[0] = tail[4];
    out[1] = tail[5];
    const closed = n >= 2 && rc.bit(m.closed, 0) === 1;
    const coded = closed ? n - 1 : n;
    let prevA = 0;
    let prevE = 0;
    // The tail and the prediction frame in locals: MakeFrame in contour_codec.cc, the same
    // operations in the same order (so the same doubles).
    let x3 = tail[0];
    let y3 = tail[1];
    let x2 = tail[2];
    let y2 = tail[3];
    let x1 = tail[4];
    let y1 = tail[5];
    l1 = -1;
    for (let k = 1; k < coded; ++k) {
      let ux = 1;
      let uy = 0;
      let lp = 0;
      let c = 0;
      let fl1 = 0;
      if (have >= 2) {
        const c1x = x1 - x2;
        const c1y = y1 - y2;
        const len = Math.sqrt(c1x * c1x + c1y * c1y);
        if (len > 0 && Number.isFinite(len)) {
          ux = c1x / len;
          uy = c1y / len;
          fl1 = len;
          lp = len;
          if (have === 3) {
            let l2 = l1;
            if (!(l2 > 0)) {
              const c2x = x2 - x3;
              const c2y = y2 - y3;
              l2 = Math.sqrt(c2x * c2x + c2y * c2y);
            }
            if (l2 > 0) lp = len * clamp(len / l2, kRatioLo, kRatioHi);
            const dx = x3 - x1;
            const dy = y3 - y1;
            const ax = dx * ux + dy * uy;
            const ay = dy * ux - dx * uy;
            const den = ax * (ax + len);
            if (den > 0 && Math.abs(ay) <= Math.abs(ax)) c = ay / den;
          }
        }
      }
      l1 = fl1;
      const kk = k < 2 ? k : 2;
      const a = rc.int(m.along[alongContext(kk, prevA)]);
      const e = rc.int(m.across[acrossContext(kk, prevE, a)]);
      const s = lp + a * step;
      const nn = c * s * (s + fl1) + e * step;
      const x = x1 + (ux * s - uy * nn);
      const y = y1 + (uy * s + ux * nn);
      if (!(Math.abs(x) <= limit) || !(Math.abs(y) <= limit)) throw outside();
      if (!rc.ok()) throw truncated('points');
      prevA = a;
      prevE = e;
      x3 = x2;
      y3 = y2;
      x2 = x1;
      y2 = y1;
      x1 = x;
      y1 = y;
      if (have < 3) have += 1;
      out[2 * k] = x;
      out[2 * k + 1] = y;
    }
    if (closed) {
      out[2 * n - 2] = out[0];
      out[2 * n - 1] = out[1];
    }
  }
  if (!rc.ok()) throw truncated('curve body');
  if (rc.pos !== bytes.length) {
    throw new ContourError(`contour: ${bytes.length - rc.pos} trailing bytes`);
  }
}

// ---------------------------------------------------------------------------------------------
// SKC3's turtle coding (Skc3Body / DecodeSkc3Body in contour_codec_skc3.cc, the rANS coder in
// common/src/skin/rans_coder.h): side information through the range coder above, then per point
// an along and an across integer as whole symbols from static per-message rANS tables.

const kTurtle = 3;
const kRuleTurtle = 4;
const kChordRule = 20000;
const kAngleBits = 14;
const kAngles = 1 << kAngleBits;
const kAngleMask = kAngles - 1;
const kMaxTurn = kAngles / 8;
const kMaxChord = 2 ** 40;
const kRecipMax = 4096;
const kTurnScale = 147996223;
const kHalfAlong = 0.6123718516919304;
const kAcross = 1.060659160255457;
const kScaleBits = 10;
const kScale = 1 << kScaleBits;
const kRansLow = 1 << 16;
const kTokenDirectBits = 4;
const kTokenDirect = 1 << kTokenDirectBits;
const kTokenMaxBits = 42;
const kAlphabet = kTokenDirect + 2 * (kTokenMaxBits - kTokenDirectBits);
const kNoSymbol = kAlphabet;
const kAlongTables = 4;
const kAlongStart = 3;
const kTables = kAlongTables + 9;

/** The cosine table of CosTable() in contour_codec_skc3.cc: the same operations, same doubles. */
const kCos = (() => {
  const t = new Float64Array(kAngles);
  const quarter = kAngles / 4;
  const eighth = kAngles / 8;
  const cc = new Float64Array(12);
  const sc = new Float64Array(12);
  cc[0] = 1;
  sc[0] = 1;
  for (let k = 1; k < 12; ++k) {
    cc[k] = -cc[k - 1] / ((2 * k - 1) * (2 * k));
    sc[k] = -sc[k - 1] / ((2 * k) * (2 * k + 1));
  }
  const c = new Float64Array(eighth + 1);
  const s = new Float64Array(eighth + 1);
  const unit = Math.PI / (kAngles / 2);
  for (let i = 0; i <= eighth; ++i) {
    const x = i * unit;
    const x2 = x * x;
    let pc = cc[11];
    let ps = sc[11];
    for (let k = 10; k >= 0; --k) {
      pc = pc * x2 + cc[k];
      ps = ps * x2 + sc[k];
    }
    c[i] = pc;
    s[i] = ps * x;
  }
  for (let i = 0; i < kAngles; ++i) {
    const q = Math.floor(i / quarter);
    const r = i % quarter;
    const v = r <= eighth ? c[r] : s[quarter - r];
    const w = r === 0 ? 0 : (quarter - r <= eighth ? c[quarter - r] : s[r]);
    t[i] = q === 0 ? v : q === 1 ? -w : q === 2 ? -v : w;
  }
  return t;
})();

const kTurn = (() => {
  const t = new Int32Array(kRecipMax + 1);
  t[0] = kTurnScale;
  for (let l = 1; l <= kRecipMax; ++l) t[l] = Math.floor(kTurnScale / l);
  return t;
})();

/** Per symbol: the zigzag value without extra bits, the extra bit count, the magnitude class. */
const kSymBase = new Float64Array(kAlphabet + 1);
const kSymBits = new Int32Array(kAlphabet + 1);
const kSymMag = new Int32Array(kAlphabet + 1);
for (let s = 0; s < kAlphabet; ++s) {
  const bits = s < kTokenDirect ? 0 : ((s - kTokenDirect) >> 1) + kTokenDirectBits - 1;
  kSymBits[s] = bits;
  kSymBase[s] = s < kTokenDirect ? s : (2 + ((s - kTokenDirect) & 1)) * kPow2[bits];
  kSymMag[s] = s === 0 ? 0 : s <= 2 ? 1 : 2;
}

/** Fills `slots` (kScale words at `at`) from frequencies (BuildRansSlots); false if malformed. */
function buildSlots(freq, slots, at) {
  let sum = 0;
  for (const f of freq) sum += f;
  if (sum === 0) {
    for (let s = 0; s < kScale; ++s) slots[at + s] = (kScale << 17) | (s << 7) | kNoSymbol;
    return true;
  }
  if (sum !== kScale) return false;
  let start = at;
  for (let i = 0; i < freq.length; ++i) {
    for (let k = 0; k < freq[i]; ++k) slots[start + k] = (freq[i] << 17) | (k << 7) | i;
    start += freq[i];
  }
  return true;
}

/**
 * Decodes SKC3's body, bytes[pos..], into p (DecodeSkc3Body): entries, counts, tables and line
 * starts from the range-coded side information, then the points. Throws ContourError where the
 * C++ decoder returns an error.
 */
function decodeTurtleBody(bytes, pos, p, nentries, nlines, rule) {
  const end = bytes.length;
  const varint = () => {
    let v = 0;
    for (let shift = 0; shift < 64; shift += 7) {
      if (pos >= end) return null;
      const b = bytes[pos++];
      if (shift < 53) v += (b & 0x7f) * 2 ** shift;
      else if (b & 0x7f) v = Infinity;
      if (!(b & 0x80)) return v;
    }
    return null;
  };
  const sideLen = varint();
  if (sideLen === null || sideLen > end - pos) throw truncated('SKC3 side information');
  const sideAt = pos;
  pos += sideLen;
  const ransLen = varint();
  if (ransLen === null || ransLen > end - pos) throw truncated('SKC3 symbols');
  const ransAt = pos;
  const rawAt = pos + ransLen;

  const rc = new RangeDecoder(bytes, sideAt, sideAt + sideLen);
  const step = p.step;
  const kind = p.kind;
  const m = {
    index: intModel(), id: intModel(), version: intModel(), count: intModel(),
    first: intModel(), nsym: intModel(), freq: intModel(),
    join: new Uint16Array(1).fill(kOne / 2), closed: new Uint16Array(1).fill(kOne / 2),
  };
  const stride = kind === kPolylineSet ? 1 : 2;
  let index = -1;
  let id = -1;
  let version = 0;
  for (let e = 0; e < nentries; ++e) {
    index = kind === kUpdate ? index + 1 + rc.int(m.index) : index + 1;
    id = id + 1 + rc.int(m.id);
    version += rc.int(m.version);
    if (!rc.ok()) throw truncated('section entries');
    if (index < 0 || index >= p.sectionCount) {
      throw new ContourError(`contour.section_index=${index} outside [0, ${p.sectionCount})`);
    }
    if (id < 0 || id > kMaxExactId || version < 0 || version > kMaxExactId) {
      throw new ContourError(`contour.section_id/version=${id}/${version} outside [0, 2^53)`);
    }
    p.index.push(index);
    p.id.push(id);
    p.version.push(version);
  }
  const counts = [];
  let total = 0;
  const cap = Math.min(kMaxContourPoints, 65536 + 512 * bytes.length);
  for (let j = 0; j < nlines; ++j) {
    const prev = j >= stride ? counts[j - stride] : 0;
    const n = prev + rc.int(m.count);
    if (!rc.ok()) throw truncated('point counts');
    if (n < 0) throw new ContourError(`contour.points=${n} for a polyline`);
    total += n;
    if (n > cap || total > cap) {
      throw new ContourError(`contour.points=${total} outside [0, ${cap}] for a ` +
                             `${bytes.length}-byte message`);
    }
    counts.push(n);
  }
  const slots = new Uint32Array(kTables * kScale);
  for (let t = 0; t < kTables; ++t) {
    const nsym = rc.int(m.nsym);
    if (nsym < 0 || nsym > kAlphabet) {
      throw new ContourError(`contour.table_symbols=${nsym} outside [0, ${kAlphabet}]`);
    }
    const freq = [];
    for (let i = 0; i < nsym; ++i) {
      const f = rc.int(m.freq);
      if (f < 0 || f > kScale) {
        throw new ContourError(`contour.table_frequency=${f} outside [0, ${kScale}]`);
      }
      freq.push(f);
    }
    if (!rc.ok()) throw truncated('symbol tables');
    if (!buildSlots(freq, slots, t * kScale)) {
      throw new ContourError(`contour: symbol table ${t} frequencies do not sum to ${kScale}`);
    }
  }
  // Per line: join, first point (fx, fy), closed, the start angle or -1.
  const join = new Uint8Array(nlines);
  const closedOf = new Uint8Array(nlines);
  const theta0 = new Int32Array(nlines).fill(-1);
  const fx = new Float64Array(nlines);
  const fy = new Float64Array(nlines);
  const valid = new Uint8Array(nlines);
  for (let j = 0; j < nlines; ++j) {
    if (counts[j] === 0) continue;
    const hasCtx = j >= stride && counts[j - stride] > 0;
    if (hasCtx) join[j] = rc.bit(m.join, 0);
    if (!join[j]) {
      fx[j] = rc.int(m.first);
      fy[j] = rc.int(m.first);
    }
    if (counts[j] >= 2) closedOf[j] = rc.bit(m.closed, 0);
    const coded = closedOf[j] ? counts[j] - 1 : counts[j];
    const carried = join[j] && valid[j - stride];
    if (coded >= 2 && !carried) theta0[j] = rc.raw(kAngleBits);
    valid[j] = carried || coded >= 2 ? 1 : 0;
    if (!rc.ok()) throw truncated('line starts');
  }
  if (!rc.ok()) throw truncated('line starts');
  if (rc.consumed() !== sideLen) {
    throw new ContourError(`contour: ${sideLen - rc.consumed()} trailing bytes in the SKC3 ` +
                           'side information');
  }

  // The rANS stream: 16-bit little-endian words; both states first.
  const ransEnd = ransAt + (ransLen & ~1);
  let wp = ransAt;
  let overrun = false;
  const word = () => {
    if (wp >= ransEnd) {
      overrun = true;
      return 0;
    }
    const w = bytes[wp] | (bytes[wp + 1] << 8);
    wp += 2;
    return w;
  };
  let x0 = word() * 65536;
  x0 += word();
  let x1 = word() * 65536;
  x1 += word();
  // The raw bits: least significant first from the low end of each byte.
  let rp = rawAt;
  let rcur = 0;
  let rleft = 0;
  let rawOverrun = false;
  const getBits = (count) => {
    let v = 0;
    let mul = 1;
    while (count > 0) {
      if (rleft === 0) {
        if (rp < end) {
          rcur = bytes[rp++];
        } else {
          rawOverrun = true;
          rcur = 0;
        }
        rleft = 8;
      }
      const t = count < rleft ? count : rleft;
      v += (rcur & ((1 << t) - 1)) * mul;
      rcur >>>= t;
      rleft -= t;
      mul *= 2 ** t;
      count -= t;
    }
    return v;
  };
  const unzigNum = (zz) => (zz % 2 === 1 ? -(zz + 1) / 2 : zz / 2);

  const limit = kMaxQuantised * step;
  const hs = step * kHalfAlong;
  const vs = step * kAcross;
  const outside = () => new ContourError('contour: decoded point outside [-2^52, 2^52] steps, ' +
                                         'or a symbol from an empty table');
  // The carried turtle of each side: theta, omega, lp, l1, actx, magE, valid.
  const turtles = [new Float64Array(7), new Float64Array(7)];
  let block = null;
  let blockAt = 0;
  let left = total;
  for (let j = 0; j < nlines; ++j) {
    const n = counts[j];
    if (2 * n > (block ? block.length - blockAt : 0)) {
      block = allocate(Float64Array, 2 * Math.max(n, Math.min(left, 1 << 16)));
      blockAt = 0;
    }
    const out = block ? block.subarray(blockAt, blockAt + 2 * n) : new Float64Array(0);
    blockAt += 2 * n;
    left -= n;
    p.lines.push(out);
    const t = turtles[j % stride];
    if (n === 0) {
      t.fill(0);
      continue;
    }
    let px;
    let py;
    if (join[j]) {
      const ctx = p.lines[j - stride];
      px = ctx[ctx.length - 2];
      py = ctx[ctx.length - 1];
    } else {
      t.fill(0);
      let rx = 0;
      let ry = 0;
      if (j >= stride && p.lines[j - stride].length) {
        const ctx = p.lines[j - stride];
        rx = roundAway(ctx[ctx.length - 2] / step);
        ry = roundAway(ctx[ctx.length - 1] / step);
      }
      const x = rx + fx[j];
      const y = ry + fy[j];
      if (Math.abs(x) > kMaxQuantised || Math.abs(y) > kMaxQuantised) {
        throw new ContourError('contour: decoded point outside [-2^52, 2^52] steps');
      }
      px = x * step;
      py = y * step;
    }
    if (theta0[j] >= 0) {
      t.fill(0);
      t[0] = theta0[j];
      t[4] = kAlongStart;
      t[6] = 1;
    }
    out[0] = px;
    out[1] = py;
    const closed = closedOf[j] === 1;
    const coded = closed ? n - 1 : n;
    let theta = t[0];
    let omega = t[1];
    let lp = t[2];
    let l1 = t[3];
    let actx = t[4];
    let magE = t[5];
    let bad = false;
    for (let k = 1; k < coded; ++k) {
      // RansDecoder::Decode, the stream read inline (a call per symbol costs more than it).
      let s = slots[actx * kScale + (x0 & (kScale - 1))];
      x0 = (s >>> 17) * (x0 >>> kScaleBits) + ((s >>> 7) & (kScale - 1));
      if (x0 < kRansLow) {
        if (wp < ransEnd) {
          x0 = x0 * 65536 + (bytes[wp] | (bytes[wp + 1] << 8));
          wp += 2;
        } else {
          overrun = true;
          x0 *= 65536;
        }
      }
      const asym = s & 127;
      const abits = kSymBits[asym];
      const a = unzigNum(kSymBase[asym] + (abits ? getBits(abits) : 0));
      const am = kSymMag[asym];
      s = slots[(kAlongTables + 3 * magE + am) * kScale + (x1 & (kScale - 1))];
      x1 = (s >>> 17) * (x1 >>> kScaleBits) + ((s >>> 7) & (kScale - 1));
      if (x1 < kRansLow) {
        if (wp < ransEnd) {
          x1 = x1 * 65536 + (bytes[wp] | (bytes[wp + 1] << 8));
          wp += 2;
        } else {
          overrun = true;
          x1 *= 65536;
        }
      }
      const esym = s & 127;
      const ebits = kSymBits[esym];
      const e = unzigNum(kSymBase[esym] + (ebits ? getBits(ebits) : 0));
      const th = (theta + omega) & kAngleMask;
      const len = lp + a;
      const ux = kCos[th];
      const uy = kCos[(th - kAngles / 4) & kAngleMask];
      const ls = (2 * len + (e & 1)) * hs;
      const es = e * vs;
      px += ls * ux - es * uy;
      py += ls * uy + es * ux;
      if (asym === kNoSymbol || esym === kNoSymbol || len > kMaxChord || len < -kMaxChord ||
          !(Math.abs(px) <= limit) || !(Math.abs(py) <= limit)) {
        bad = true;
        break;
      }
      const lc = len < 1 ? 1 : len > kRecipMax ? kRecipMax : len;
      const ec = e < -lc ? -lc : e > lc ? lc : e;
      const d = (ec * kTurn[lc]) >> 16;
      theta = (th + d) & kAngleMask;
      omega = clamp(omega + d, -kMaxTurn, kMaxTurn);
      // The chord in half spacings (the row's parity is half a spacing along), continued.
      const half = 2 * len + (e & 1);
      if (rule) {
        // SKC4: RuleChord in contour_codec_skc3.cc, the same doubles.
        if (half <= 0) {
          lp = Math.floor(half / 2);
        } else {
          const lo = half - Math.floor(half / 4);
          const hi = half + Math.floor(half / 4) + 2;
          const w = omega < 0 ? -omega : omega;
          let g = hi;
          if (w > 0) {
            const c = Math.sqrt((kChordRule * (half < 1048576 ? half : 1048576)) / w);
            g = c < lo ? lo : c > hi ? hi : Math.floor(c);
          }
          lp = Math.floor(g / 2);
        }
      } else {
        const mm = half > 0 ? Math.floor((half * 13) / 256) : 0;
        lp = Math.floor((half + clamp(half - l1, -mm, mm)) / 2);
      }
      l1 = half;
      actx = am;
      magE = kSymMag[esym];
      out[2 * k] = px;
      out[2 * k + 1] = py;
    }
    if (bad) throw outside();
    if (overrun) throw truncated('points');
    t[0] = theta;
    t[1] = omega;
    t[2] = lp;
    t[3] = l1;
    t[4] = actx;
    t[5] = magE;
    if (closed) {
      out[2 * n - 2] = out[0];
      out[2 * n - 1] = out[1];
    }
  }
  if (overrun || (ransLen & 1) || wp !== ransEnd || x0 !== kRansLow || x1 !== kRansLow) {
    throw new ContourError('contour: the SKC3 symbol stream does not end where it began');
  }
  // Every byte used, the unused high bits of the last one zero.
  if (rawOverrun || rp !== end || (rleft > 0 && rcur !== 0)) {
    throw new ContourError('contour: the SKC3 raw bits do not end with the last symbol');
  }
}

// ---------------------------------------------------------------------------------------------
// The contour format.

/** A bounded reader over the message (the C++ Reader). */
class Reader {
  constructor(bytes) {
    this.bytes = bytes;
    this.pos = 0;
  }
  /** A 64-bit varint (at most 10 bytes); null when cut short. */
  varint() {
    const r = readVarint(this.bytes, this.pos, this.bytes.length, 10, 64);
    if (!r) return null;
    this.pos += r.size;
    return r.value;
  }
}

/** Where line j's prediction context is: the previous line of its side (skins) or the previous
 *  line (polyline sets). */
function context(lines, j, kind) {
  const stride = kind === kPolylineSet ? 1 : 2;
  return j >= stride ? lines[j - stride] : null;
}

/**
 * The prediction of point k (x at out[0], y at out[1]) of quantised line q (interleaved) from its
 * points 0..k-1: see Predict in contour_codec.cc. Every double operation is the C++ one, in the
 * same order, so both sides predict the same integers. Results are exact integers, Numbers or
 * (only for hostile input) BigInts.
 */
function predict(q, k, ctx, out) {
  if (k === 1) {
    const n = ctx ? ctx.length : 0;
    if (n >= 4 && ctx[n - 2] === q[0] && ctx[n - 1] === q[1]) {
      out[0] = addExact(q[0], ctx[n - 2] - ctx[n - 4]);
      out[1] = addExact(q[1], ctx[n - 1] - ctx[n - 3]);
    } else {
      out[0] = q[0];
      out[1] = q[1];
    }
    return;
  }
  const p1x = q[2 * k - 2];
  const p1y = q[2 * k - 1];
  const ax = p1x - q[2 * k - 4];
  const ay = p1y - q[2 * k - 3];
  let zx = ax;
  let zy = ay;
  if (k >= 3) {
    const bx = q[2 * k - 4] - q[2 * k - 6];
    const by = q[2 * k - 3] - q[2 * k - 5];
    const bb = bx * bx + by * by;
    if (bb > 0) {
      const re = (ax * bx + ay * by) / bb;
      const im = (ay * bx - ax * by) / bb;
      const cx = re * ax - im * ay;
      const cy = re * ay + im * ax;
      if (cx * cx + cy * cy <= 16 * (ax * ax + ay * ay) && Math.abs(cx) < kMaxQuantised &&
          Math.abs(cy) < kMaxQuantised) {
        zx = cx;
        zy = cy;
      }
    }
  }
  out[0] = addExact(p1x, roundAway(zx));
  out[1] = addExact(p1y, roundAway(zy));
}

/** pred + residual when within [-2^52, 2^52], else a ContourError (AddBounded). */
function bounded(pred, residual) {
  const v = addExact(pred, residual);
  if (typeof v !== 'number' || Math.abs(v) > kMaxQuantised) {
    throw new ContourError('contour: decoded point outside [-2^52, 2^52] steps');
  }
  return v;
}

/** An id or version as a Number; ids beyond 2^53 (never sent by a real skin) are refused. */
function exactId(v, field) {
  if (typeof v === 'bigint') {
    throw new ContourError(`contour.${field}=${v} outside [0, 2^53) (JavaScript numbers)`);
  }
  return v;
}

/** Parses and decodes a whole message (Parse in contour_codec.cc). */
function parse(bytes) {
  if (!(bytes instanceof Uint8Array)) throw new ContourError('contour: bytes must be a Uint8Array');
  const r = new Reader(bytes);
  if (bytes.length < 4 || kMagic.some((m, i) => bytes[i] !== m) ||
      (bytes[3] !== 0x31 && bytes[3] !== 0x32 && bytes[3] !== 0x33 && bytes[3] !== 0x34)) {
    throw new ContourError('contour: bad magic (want SKC4, SKC3, SKC2 or SKC1)');
  }
  const skc4 = bytes[3] === 0x34;
  const skc3 = bytes[3] === 0x33 || skc4;  // the same body but for the chord predictor
  const skc2 = bytes[3] === 0x32 || skc3;  // the same header
  r.pos = 4;
  if (r.pos >= bytes.length) throw truncated('kind');
  const kind = bytes[r.pos++];
  if (kind > kUpdate) throw new ContourError(`contour.kind=${kind} outside [0, 2]`);
  if (bytes.length - r.pos < 8) throw truncated('step');
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const step = view.getFloat64(r.pos, true);
  r.pos += 8;
  if (!Number.isFinite(step) || !(step > 0)) {
    throw new ContourError(`contour.step=${step} outside (0, inf)`);
  }
  if (r.pos >= bytes.length) throw truncated('coding');
  const coding = bytes[r.pos++];
  if (skc4 ? coding !== kRuleTurtle : skc3 ? coding !== kTurtle : skc2 ? coding !== kCurve
    : coding > kRans) {
    throw new ContourError(`contour.coding=${coding} outside ` +
                           (skc4 ? '[4, 4] for SKC4' : skc3 ? '[3, 3] for SKC3' : skc2 ? '[2, 2] for SKC2'
                             : '[0, 1] for SKC1'));
  }

  const p = { kind, step, coding, scheme: null, sectionCount: 0, spliceAt: 0, removed: 0,
              inserted: 0, index: [], id: [], version: [], lines: [] };
  let nlines = 0;
  if (kind === kPolylineSet) {
    const n = r.varint();
    if (n === null) throw truncated('polyline count');
    if (n > kMaxContourPolylines) {
      throw new ContourError(`contour.polylines=${n} outside [0, ${kMaxContourPolylines}]`);
    }
    nlines = n;
  } else {
    const count = r.varint();
    if (count === null) throw truncated('section count');
    if (count > kMaxContourPolylines) {
      throw new ContourError(`contour.sections=${count} outside [0, ${kMaxContourPolylines}]`);
    }
    p.sectionCount = count;
    let entries = count;
    if (kind === kUpdate) {
      const spliceAt = r.varint();
      const removed = spliceAt === null ? null : r.varint();
      const inserted = removed === null ? null : r.varint();
      entries = inserted === null ? null : r.varint();
      if (entries === null) throw truncated('update header');
      if (entries > count) {
        throw new ContourError(`contour.changed=${entries} outside [0, ${count}]`);
      }
      Object.assign(p, { spliceAt, removed, inserted });
    }
    for (let i = 0; i < entries && !skc2; ++i) {
      let idx = i;
      if (kind === kUpdate) {
        idx = r.varint();
        if (idx === null) throw truncated('section index');
      }
      const id = r.varint();
      const version = id === null ? null : r.varint();
      if (version === null) throw truncated('section id');
      if (idx >= count) {
        throw new ContourError(`contour.section_index=${idx} outside [0, ${count})`);
      }
      p.index.push(idx);
      p.id.push(exactId(id, 'section_id'));
      p.version.push(exactId(version, 'section_version'));
    }
    nlines = 2 * entries;
  }
  if (coding === kCurve) {
    decodeCurveBody(bytes, r.pos, p, kind === kPolylineSet ? 0 : nlines / 2, nlines);
    return p;
  }
  if (coding === kTurtle || coding === kRuleTurtle) {
    decodeTurtleBody(bytes, r.pos, p, kind === kPolylineSet ? 0 : nlines / 2, nlines,
                     coding === kRuleTurtle);
    return p;
  }

  // Point counts and first points (grown as read: a hostile line count costs no memory until
  // its bytes are there).
  const counts = [];
  const firsts = [];
  const cap = Math.min(kMaxContourPoints, 65536 + 256 * bytes.length);
  let total = 0;
  let nres = 0;
  for (let i = 0; i < nlines; ++i) {
    const n = r.varint();
    if (n === null) throw truncated('point count');
    total = n > kMaxContourPoints ? n : total + n;
    // Even entropy-coded, a point costs far more than 1/256 byte: a claim beyond that is a lie
    // that would only make us allocate.
    if (total > cap) {
      throw new ContourError(`contour.points=${total} outside [0, ${cap}] for a ` +
                             `${bytes.length}-byte message`);
    }
    counts.push(n);
    if (n === 0) {
      firsts.push(0, 0);
      continue;
    }
    const fx = r.varint();
    const fy = fx === null ? null : r.varint();
    if (fy === null) throw truncated('first point');
    firsts.push(fx, fy);
    nres += 2 * (n - 1);
  }

  // The residual stream.
  let res;
  let big = null;  // index -> BigInt, for varint residuals of 2^53 and above
  if (coding === kVarint) {
    if (nres > bytes.length - r.pos) throw truncated('residuals');  // >= 1 byte each
    res = new Float64Array(nres);
    for (let i = 0; i < nres; ++i) {
      const v = r.varint();
      if (v === null) throw truncated('residuals');
      if (typeof v === 'bigint') {
        (big ??= new Map()).set(i, v);
      } else {
        res[i] = v;
      }
    }
  } else {
    res = allocate(Uint32Array, nres);
    if (nres > 0) {
      const buf = new DracoBuffer(bytes, r.pos, bytes.length);
      const info = decodeSymbols(nres, 2, buf, res);
      p.scheme = info.scheme;
      p.precisionBits = info.precisionBits;
      r.pos = buf.pos;
    }
  }
  if (r.pos !== bytes.length) {
    throw new ContourError(`contour: ${bytes.length - r.pos} trailing bytes`);
  }

  // Undo the prediction, line by line, in integer plane coordinates.
  const q = [];
  const pred = [0, 0];
  let next = 0;
  for (let i = 0; i < nlines; ++i) {
    const n = counts[i];
    const line = allocate(Float64Array, 2 * n);
    q.push(line);
    if (n === 0) {
      p.lines.push(line);
      continue;
    }
    const ctx = context(q, i, kind);
    const fx = ctx && ctx.length ? ctx[ctx.length - 2] : 0;
    const fy = ctx && ctx.length ? ctx[ctx.length - 1] : 0;
    line[0] = bounded(fx, unzig(firsts[2 * i]));
    line[1] = bounded(fy, unzig(firsts[2 * i + 1]));
    for (let k = 1; k < n; ++k) {
      predict(line, k, ctx, pred);
      const dx = big?.get(next) ?? res[next];
      const dy = big?.get(next + 1) ?? res[next + 1];
      next += 2;
      line[2 * k] = bounded(pred[0], unzig(dx));
      line[2 * k + 1] = bounded(pred[1], unzig(dy));
    }
    const out = new Float64Array(2 * n);
    for (let j = 0; j < 2 * n; ++j) out[j] = line[j] * step;
    p.lines.push(out);
  }
  return p;
}

/** new Type(n), with a hostile size's RangeError turned into a ContourError. */
function allocate(Type, n) {
  try {
    return new Type(n);
  } catch (e) {
    throw new ContourError(`contour: ${n} values do not fit in memory (${e.message})`);
  }
}

/**
 * Decodes a polyline set (EncodeContours' output).
 * @param {Uint8Array} bytes
 * @returns {Float64Array[]} each polyline's points as interleaved x, y (plane coordinates); an
 *   SKC2 message's lines are views into shared blocks (copy one before transferring its buffer)
 * @throws {ContourError} for truncated, oversized or malformed input, or a skin message
 */
export function decodeContours(bytes) {
  const p = parse(bytes);
  if (p.kind !== kPolylineSet) {
    throw new ContourError(`contour.kind=${p.kind} is a skin message, not a polyline set`);
  }
  return p.lines;
}

/**
 * What a message is and how it was coded, for diagnostics and tests:
 * {kind, step, coding (0 varints, 1 rANS), scheme ('tagged' | 'raw' | null), precisionBits,
 *  polylines, points}. Throws ContourError as decodeContours does.
 */
export function describeContour(bytes) {
  const p = parse(bytes);
  return {
    kind: p.kind, step: p.step, coding: p.coding, scheme: p.scheme,
    precisionBits: p.precisionBits ?? null, polylines: p.lines.length,
    points: p.lines.reduce((s, l) => s + l.length / 2, 0),
  };
}

/**
 * A thin client's copy of a skin's contours (skin::ContourView): apply snapshots and updates in
 * order. `sections` is [{id, version, plus, minus}], plus/minus interleaved x, y; treat it as
 * read-only (apply replaces it). Not shared between threads (a value per page).
 */
export class ContourView {
  constructor() {
    this._sections = [];
    this._step = 0;
  }

  get sections() {
    return this._sections;
  }

  get step() {
    return this._step;
  }

  /**
   * Applies a snapshot (replaces everything) or an update (splice, then changed sections).
   * @param {Uint8Array} bytes
   * @throws {ContourError} for bad bytes, a polyline set, or an update that does not fit the
   *   view; the view is then unchanged.
   */
  apply(bytes) {
    const p = parse(bytes);
    if (p.kind === kPolylineSet) {
      throw new ContourError('contour.kind=0 is a polyline set, not a skin message');
    }
    const size = this._sections.length;
    let next;
    const filled = [];
    if (p.kind === kSnapshot) {
      next = new Array(p.sectionCount).fill(null);
      for (let k = 0; k < next.length; ++k) filled.push(false);
    } else {
      const { spliceAt, removed, inserted } = p;
      if (spliceAt > size || removed > size - spliceAt) {
        throw new ContourError(`contour.splice at ${spliceAt} removing ${removed} outside the ` +
                               `view's ${size} sections`);
      }
      if (inserted > p.index.length) {
        throw new ContourError(`contour.inserted=${inserted} outside [0, ${p.index.length}] ` +
                               '(the changed sections)');
      }
      if (size - removed + inserted !== p.sectionCount) {
        throw new ContourError(`contour.sections=${p.sectionCount} does not match the view ` +
                               'after the splice');
      }
      next = this._sections.slice(0, spliceAt);
      for (let k = 0; k < inserted; ++k) next.push(null);
      next.push(...this._sections.slice(spliceAt + removed));
      for (let k = 0; k < next.length; ++k) filled.push(next[k] !== null);
    }
    for (let e = 0; e < p.index.length; ++e) {
      next[p.index[e]] = { id: p.id[e], version: p.version[e], plus: p.lines[2 * e],
                           minus: p.lines[2 * e + 1] };
      filled[p.index[e]] = true;
    }
    const hole = filled.indexOf(false);
    if (hole >= 0) throw new ContourError(`contour: section ${hole} left without points`);
    this._sections = next;
    this._step = p.step;
  }

  /**
   * The + (side > 0) or - list of the whole chain, consecutive sections' shared end point once
   * (skin::ContourView::Chain).
   * @returns {Float64Array} interleaved x, y
   */
  chain(side) {
    let n = 0;
    for (const s of this._sections) {
      const l = side > 0 ? s.plus : s.minus;
      if (l.length) n += n ? l.length - 2 : l.length;
    }
    const out = new Float64Array(n);
    let at = 0;
    for (const s of this._sections) {
      const l = side > 0 ? s.plus : s.minus;
      if (!l.length) continue;
      const from = at ? 2 : 0;
      out.set(l.subarray(from), at);
      at += l.length - from;
    }
    return out;
  }
}
