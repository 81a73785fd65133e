/// @brief The contour codec: SKC2's curve coding (a circle-continuing prediction in the curve's
/// own frame, residuals on a rotated lattice, an adaptive range coder), and SKC1's quantise,
/// predict, zigzag, then varints or Draco's entropy coder.
#include "sculpt/skin/contour_codec.h"

#include <draco/compression/entropy/symbol_decoding.h>
#include <draco/compression/entropy/symbol_encoding.h>
#include <draco/core/decoder_buffer.h>
#include <draco/core/encoder_buffer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>

#include "contour_codec_internal.h"
#include "range_coder.h"
#include "sculpt/core/check.h"

namespace sculpt::skin {
namespace {

constexpr char kMagic1[4] = {'S', 'K', 'C', '1'};
constexpr char kMagic2[4] = {'S', 'K', 'C', '2'};
constexpr char kMagic3[4] = {'S', 'K', 'C', '3'};
constexpr char kMagic4[4] = {'S', 'K', 'C', '4'};
enum Kind : uint8_t { kPolylineSet = 0, kSnapshot = 1, kUpdate = 2 };
enum Coding : uint8_t { kVarint = 0, kRans = 1, kCurve = 2, kTurtle = 3, kRuleTurtle = 4 };
constexpr double kMaxQuantised = 4503599627370496.0;  // 2^52

using Q = std::array<int64_t, 2>;
using QLine = std::vector<Q>;

void PutVarint(std::string& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

uint64_t Zig(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
int64_t Unzig(uint64_t u) { return static_cast<int64_t>(u >> 1) ^ -static_cast<int64_t>(u & 1); }

/// Bounded reader over untrusted bytes.
struct Reader {
  std::string_view in;
  size_t pos = 0;
  bool Varint(uint64_t* v) {
    uint64_t r = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (pos >= in.size()) return false;
      const uint8_t b = static_cast<uint8_t>(in[pos++]);
      r |= static_cast<uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) {
        *v = r;
        return true;
      }
    }
    return false;
  }
  bool Bytes(void* dst, size_t n) {
    if (in.size() - pos < n) return false;
    std::memcpy(dst, in.data() + pos, n);
    pos += n;
    return true;
  }
};

/// Where a line starts: the end of its context line (the previous line of the same side in a skin
/// message, the previous line in a polyline set), which is exactly the joint for consecutive
/// skin sections; the origin without one.
Q PredictFirst(const QLine* ctx) {
  return ctx && !ctx->empty() ? ctx->back() : Q{0, 0};
}

/// Constant-curvature prediction of point k of a line from its decoded points 0..k-1: the last
/// step turned and scaled as the step before it was (complex a * a / b); integer arithmetic in and
/// out, IEEE double in between (+ - * / only, so encoder and decoder agree on every platform).
/// The second point continues the context line's last step (G1 across skin joints).
Q Predict(const QLine& q, size_t k, const QLine* ctx) {
  if (k == 1) {
    if (ctx && ctx->size() >= 2 && ctx->back() == q[0]) {
      const Q& a = (*ctx)[ctx->size() - 1];
      const Q& b = (*ctx)[ctx->size() - 2];
      return {q[0][0] + (a[0] - b[0]), q[0][1] + (a[1] - b[1])};
    }
    return q[0];
  }
  const Q& p1 = q[k - 1];
  const double ax = static_cast<double>(p1[0] - q[k - 2][0]);
  const double ay = static_cast<double>(p1[1] - q[k - 2][1]);
  double zx = ax, zy = ay;
  if (k >= 3) {
    const double bx = static_cast<double>(q[k - 2][0] - q[k - 3][0]);
    const double by = static_cast<double>(q[k - 2][1] - q[k - 3][1]);
    const double bb = bx * bx + by * by;
    if (bb > 0) {
      const double re = (ax * bx + ay * by) / bb, im = (ay * bx - ax * by) / bb;
      const double cx = re * ax - im * ay, cy = re * ay + im * ax;
      // A wild ratio (a step after a near-stop) predicts worse than a plain step.
      if (cx * cx + cy * cy <= 16 * (ax * ax + ay * ay) && std::abs(cx) < kMaxQuantised &&
          std::abs(cy) < kMaxQuantised) {
        zx = cx, zy = cy;
      }
    }
  }
  return {p1[0] + static_cast<int64_t>(std::llround(zx)),
          p1[1] + static_cast<int64_t>(std::llround(zy))};
}

Status Quantise(const std::vector<const Polyline2*>& lines, double step, std::vector<QLine>* out) {
  SCULPT_RETURN_IF_ERROR(CheckRange("step", step, 0, 1e300));
  if (!(step > 0)) return Outside("step", FormatNumber(step), "(0, inf)");
  out->clear();
  out->reserve(lines.size());
  for (size_t i = 0; i < lines.size(); ++i) {
    QLine q;
    q.reserve(lines[i]->size());
    for (size_t j = 0; j < lines[i]->size(); ++j) {
      const Vec2 p = (*lines[i])[j];
      const double x = p.x / step, y = p.y / step;
      if (!p.IsFinite() || !(std::abs(x) < kMaxQuantised) || !(std::abs(y) < kMaxQuantised)) {
        return Outside(
            std::string("polylines[") + std::to_string(i) + "][" + std::to_string(j) + "]",
            std::string("(") + FormatNumber(p.x) + ", " + FormatNumber(p.y) +
                std::string(") / step=") + FormatNumber(step) + " is not finite or",
            "[-2^52, 2^52]");
      }
      q.push_back({static_cast<int64_t>(std::llround(x)), static_cast<int64_t>(std::llround(y))});
    }
    out->push_back(std::move(q));
  }
  return Status::Ok();
}

/// Magic, kind, step, coding, `header`, the per-line counts and first points, the residuals.
/// The context line of line j (see PredictFirst).
const QLine* Context(const std::vector<QLine>& lines, size_t j, Kind kind) {
  const size_t stride = kind == kPolylineSet ? 1 : 2;
  return j >= stride ? &lines[j - stride] : nullptr;
}

std::string Assemble(Kind kind, double step, const std::string& header,
                     const std::vector<QLine>& lines) {
  std::string firsts;
  std::vector<uint64_t> res;
  for (size_t j = 0; j < lines.size(); ++j) {
    const QLine& q = lines[j];
    const QLine* ctx = Context(lines, j, kind);
    PutVarint(firsts, q.size());
    if (q.empty()) continue;
    const Q first = PredictFirst(ctx);
    PutVarint(firsts, Zig(q[0][0] - first[0]));
    PutVarint(firsts, Zig(q[0][1] - first[1]));
    for (size_t k = 1; k < q.size(); ++k) {
      const Q p = Predict(q, k, ctx);
      res.push_back(Zig(q[k][0] - p[0]));
      res.push_back(Zig(q[k][1] - p[1]));
    }
  }
  std::string varints;
  bool fits32 = true;
  for (uint64_t r : res) {
    PutVarint(varints, r);
    fits32 = fits32 && r <= std::numeric_limits<uint32_t>::max() / 2;
  }
  Coding coding = kVarint;
  std::string body = varints;
  if (fits32 && !res.empty()) {
    std::vector<uint32_t> sym(res.begin(), res.end());
    draco::EncoderBuffer buf;
    if (draco::EncodeSymbols(sym.data(), static_cast<int>(sym.size()), 2, nullptr, &buf) &&
        buf.size() < varints.size()) {
      coding = kRans;
      body.assign(buf.data(), buf.size());
    }
  }
  std::string out(kMagic1, 4);
  out.push_back(static_cast<char>(kind));
  char sb[8];
  std::memcpy(sb, &step, 8);  // little-endian hosts only (x86-64, aarch64)
  out.append(sb, 8);
  out.push_back(static_cast<char>(coding));
  out += header;
  out += firsts;
  out += body;
  return out;
}

struct Parsed {
  Kind kind = kPolylineSet;
  double step = 0;
  uint64_t section_count = 0, splice_at = 0, removed = 0, inserted = 0;
  std::vector<uint64_t> index, id, version;  // per section entry (snapshot or update)
  std::vector<Polyline2> lines;
};

/// a + b into *out when it neither overflows nor leaves [-2^52, 2^52] (untrusted residuals).
bool AddBounded(int64_t a, int64_t b, int64_t* out) {
  int64_t r = 0;
  if (__builtin_add_overflow(a, b, &r)) return false;
  if (std::abs(static_cast<double>(r)) > kMaxQuantised) return false;
  *out = r;
  return true;
}

Status Truncated(const char* what) { return DataLoss(std::string("contour: truncated ") + what); }

// ---------------------------------------------------------------------------------------------
// SKC2's curve coding. Every decoded point is p1 + s u + n v: p1 the previous decoded point, u the
// direction of the last step and v = u turned left, s = the predicted step length plus a * step,
// n = the parabola through the last three points evaluated at s plus e * step. The encoder
// rounds a and e, so the decoded point is within step/2 of the input along u and along v, hence
// within step/sqrt(2); it checks every point as the decoder will compute it.
// Only + - * / and sqrt on doubles, in the order written (the JS decoder repeats it; the file
// is built with -ffp-contract=off so no platform fuses a multiply-add).

constexpr double kRatioLo = 0.95;  // the step-length ratio carried on, clamped to [0.95, 1/0.95]
constexpr double kRatioHi = 1 / 0.95;
constexpr int kAlongContexts = 6;
constexpr int kAcrossContexts = 10;

/// The last three decoded points of a line, oldest first (n of them valid).
struct Tail {
  Vec2 p[3];
  int n = 0;
  void Push(Vec2 v) {
    p[0] = p[1];
    p[1] = p[2];
    p[2] = v;
    if (n < 3) ++n;
  }
};

/// The prediction frame at the tail's last point.
struct Frame {
  double x = 0, y = 0;    // p1
  double ux = 1, uy = 0;  // unit direction of the last step
  double lp = 0;          // predicted length of the next step
  double l1 = 0;          // length of the last step
  double c = 0;           // parabola n(s) = c s (s + l1) through p3, p2, p1
};

/// `l2` is the length of the step before the last (the previous frame's l1, the same double) or
/// negative when unknown.
[[gnu::always_inline]] inline Frame MakeFrame(const Tail& t, double l2_known = -1) {
  Frame f;
  const Vec2 p1 = t.p[2];
  f.x = p1.x;
  f.y = p1.y;
  if (t.n < 2) return f;
  const Vec2 p2 = t.p[1];
  const double c1x = p1.x - p2.x, c1y = p1.y - p2.y;
  const double l1 = std::sqrt(c1x * c1x + c1y * c1y);
  if (!(l1 > 0) || !std::isfinite(l1)) return f;
  f.ux = c1x / l1;
  f.uy = c1y / l1;
  f.l1 = l1;
  f.lp = l1;
  if (t.n < 3) return f;
  const Vec2 p3 = t.p[0];
  double l2 = l2_known;
  if (l2 < 0) {
    const double c2x = p2.x - p3.x, c2y = p2.y - p3.y;
    l2 = std::sqrt(c2x * c2x + c2y * c2y);
  }
  if (l2 > 0) f.lp = l1 * std::clamp(l1 / l2, kRatioLo, kRatioHi);
  const double dx = p3.x - p1.x, dy = p3.y - p1.y;
  const double x3 = dx * f.ux + dy * f.uy;
  const double y3 = dy * f.ux - dx * f.uy;
  const double den = x3 * (x3 + l1);
  // Only a gentle turn (under 45 degrees) is continued; anything else predicts a straight step.
  if (den > 0 && std::abs(y3) <= std::abs(x3)) f.c = y3 / den;
  return f;
}

/// The along offset s and the across offset n of a point from frame f.
[[gnu::always_inline]] inline double AcrossAt(const Frame& f, double s) {
  return f.c * s * (s + f.l1);
}
[[gnu::always_inline]] inline Vec2 Place(const Frame& f, double s, double n) {
  return {f.x + (f.ux * s - f.uy * n), f.y + (f.uy * s + f.ux * n)};
}

int AlongContext(int k, int64_t prev) {
  if (k == 1) return 5;
  const uint64_t m = prev < 0 ? 0 - static_cast<uint64_t>(prev) : static_cast<uint64_t>(prev);
  return m == 0 ? 0 : m <= 2 ? 1 : m <= 8 ? 2 : m <= 32 ? 3 : 4;
}
int AcrossContext(int k, int64_t prev_e, int64_t a) {
  if (k == 1) return 9;
  auto small = [](int64_t v) {
    const uint64_t m = v < 0 ? 0 - static_cast<uint64_t>(v) : static_cast<uint64_t>(v);
    return static_cast<int>(std::min<uint64_t>(m, 2));
  };
  return small(prev_e) + 3 * small(a);
}

using Entry = internal::SectionEntry;

/// Section ids and versions must be exact JavaScript numbers in SKC2.
constexpr uint64_t kMaxExactId = (1ull << 53) - 1;

/// The adaptive models of one message.
struct CurveModels {
  internal::IntModel index, id, version;
  internal::IntModel count, first;
  internal::BitModel join, closed;
  internal::IntModel along[kAlongContexts], across[kAcrossContexts];
};

/// The last up-to-three points of `ctx` (which ends at the joint), as a tail.
Tail TailOf(const Polyline2& ctx) {
  Tail t;
  for (size_t i = ctx.size() > 3 ? ctx.size() - 3 : 0; i < ctx.size(); ++i) t.Push(ctx[i]);
  return t;
}

/// The rounding of x / step to an integer when it is a plane coordinate of at most 2^52 steps.
bool StepIndex(double v, double step, int64_t* out) {
  const double x = v / step;
  if (!(std::abs(x) <= kMaxQuantised)) return false;
  *out = static_cast<int64_t>(std::llround(x));
  return true;
}

bool Codable(int64_t v) {
  return v >= -static_cast<int64_t>(internal::kMaxCodedMagnitude) &&
         v <= static_cast<int64_t>(internal::kMaxCodedMagnitude);
}

/// A decoded coordinate must be finite and within 2^52 steps (as SKC1's integers are).
bool InPlane(Vec2 p, double step) {
  return std::abs(p.x) <= kMaxQuantised * step && std::abs(p.y) <= kMaxQuantised * step;
}

/// The range-coded body of the curve coding, or nullopt when some point cannot be placed within
/// step/sqrt(2) in doubles (coordinates so large against the step that rounding eats the margin),
/// in which case the caller writes SKC1.
std::optional<std::string> CurveBody(Kind kind, double step, const std::vector<Entry>& entries,
                                     const std::vector<const Polyline2*>& lines) {
  const double bound2 = step * step / 2;
  internal::RangeEncoder rc;
  auto models = std::make_unique<CurveModels>();
  const size_t stride = kind == kPolylineSet ? 1 : 2;
  // Entries as differences from the previous one's index + 1, id + 1 and version.
  Entry prev{static_cast<uint64_t>(-1), static_cast<uint64_t>(-1), 0};
  for (const Entry& e : entries) {
    if (e.id > kMaxExactId || e.version > kMaxExactId) return std::nullopt;
    if (kind == kUpdate) rc.Int(models->index, static_cast<int64_t>(e.index - (prev.index + 1)));
    rc.Int(models->id, static_cast<int64_t>(e.id) - static_cast<int64_t>(prev.id + 1));
    rc.Int(models->version, static_cast<int64_t>(e.version) - static_cast<int64_t>(prev.version));
    prev = e;
  }
  for (size_t j = 0; j < lines.size(); ++j) {
    const size_t prev = j >= stride ? lines[j - stride]->size() : 0;
    rc.Int(models->count, static_cast<int64_t>(lines[j]->size()) - static_cast<int64_t>(prev));
  }
  std::vector<Polyline2> decoded(lines.size());
  for (size_t j = 0; j < lines.size(); ++j) {
    const Polyline2& in = *lines[j];
    if (in.empty()) continue;
    Polyline2& out = decoded[j];
    out.reserve(in.size());
    const Polyline2* ctx = j >= stride ? &decoded[j - stride] : nullptr;
    Tail tail;
    if (ctx && !ctx->empty()) {
      const Vec2 d = in[0] - ctx->back();
      const bool join = d.x * d.x + d.y * d.y <= bound2;
      rc.Bit(models->join, join);
      if (join) tail = TailOf(*ctx);
    }
    if (tail.n == 0) {
      int64_t rx = 0, ry = 0, x = 0, y = 0;
      if (ctx && !ctx->empty() &&
          (!StepIndex(ctx->back().x, step, &rx) || !StepIndex(ctx->back().y, step, &ry))) {
        return std::nullopt;
      }
      if (!StepIndex(in[0].x, step, &x) || !StepIndex(in[0].y, step, &y)) return std::nullopt;
      if (!Codable(x - rx) || !Codable(y - ry)) return std::nullopt;
      rc.Int(models->first, x - rx);
      rc.Int(models->first, y - ry);
      const Vec2 p{static_cast<double>(x) * step, static_cast<double>(y) * step};
      const Vec2 d = p - in[0];
      if (!(d.x * d.x + d.y * d.y <= bound2)) return std::nullopt;
      tail.Push(p);
    }
    out.push_back(tail.p[2]);
    // A closed line (last point == first, as slice loops come) ends on its decoded first point.
    const bool closed = in.size() >= 2 && in.back() == in.front();
    if (in.size() >= 2) rc.Bit(models->closed, closed);
    const size_t coded = closed ? in.size() - 1 : in.size();
    int64_t prev_a = 0, prev_e = 0;
    for (size_t k = 1; k < coded; ++k) {
      const Frame f = MakeFrame(tail);
      const double dx = in[k].x - f.x, dy = in[k].y - f.y;
      const double ta = (dx * f.ux + dy * f.uy - f.lp) / step;
      if (!(std::abs(ta) < kMaxQuantised)) return std::nullopt;
      const int64_t a0 = std::llround(ta);
      bool placed = false;
      int64_t a = 0, e = 0;
      Vec2 p;
      // The rounded offsets nearly always place the point; rounding in the last bits can push it
      // just outside, and then a neighbour does.
      for (int64_t da : {0, -1, 1}) {
        a = a0 + da;
        const double s = f.lp + static_cast<double>(a) * step;
        const double np = AcrossAt(f, s);
        const double te = (dy * f.ux - dx * f.uy - np) / step;
        if (!(std::abs(te) < kMaxQuantised)) return std::nullopt;
        const int64_t e0 = std::llround(te);
        for (int64_t de : {0, -1, 1}) {
          e = e0 + de;
          p = Place(f, s, np + static_cast<double>(e) * step);
          const Vec2 d = p - in[k];
          if (d.x * d.x + d.y * d.y <= bound2 && InPlane(p, step)) {
            placed = true;
            break;
          }
        }
        if (placed) break;
      }
      if (!placed) return std::nullopt;
      rc.Int(models->along[AlongContext(static_cast<int>(std::min<size_t>(k, 2)), prev_a)], a);
      rc.Int(models->across[AcrossContext(static_cast<int>(std::min<size_t>(k, 2)), prev_e, a)], e);
      prev_a = a;
      prev_e = e;
      tail.Push(p);
      out.push_back(p);
    }
    if (closed) out.push_back(out.front());
  }
  return rc.Finish();
}

/// Which format an encoder writes: the newest that places every point (SKC3, then SKC2, then
/// SKC1), or one named for the benchmark and the fixtures.
/// kBest writes SKC4 for messages of a skin sampled for it (SkinOptions::sample_for_codec) and
/// SKC3 otherwise.
enum class Format { kBest, kSkc4, kSkc3, kSkc2, kSkc1 };

/// Below this many points a message also tries SKC2 and keeps the smaller: SKC3's tables cost
/// a few hundred bytes, which a short update does not earn back.
constexpr size_t kSkc3TryBoth = 4096;

/// The message: SKC3 where it places every point (or SKC2 where that is smaller), SKC2 where
/// SKC3 cannot, SKC1 where neither can. `header` holds the kind's counts; SKC1 writes the section
/// entries after it as varints, SKC2 and SKC3 code them in their bodies.
std::string Encode(Kind kind, double step, const std::string& header,
                   const std::vector<Entry>& entries, const std::vector<const Polyline2*>& lines,
                   const std::vector<QLine>& q, Format format = Format::kBest,
                   bool prefer_skc4 = false, const std::vector<bool>* fresh = nullptr) {
  std::optional<std::string> body;
  const char* magic = kMagic2;
  Coding coding = kCurve;
  if (format == Format::kBest || format == Format::kSkc3 || format == Format::kSkc4) {
    size_t points = 0;
    for (const Polyline2* l : lines) points += l->size();
    const bool skc4 = format == Format::kSkc4 || (format == Format::kBest && prefer_skc4);
    body = internal::Skc3Body(kind, step, entries, lines, skc4, skc4 ? fresh : nullptr);
    if (body) {
      magic = skc4 ? kMagic4 : kMagic3;
      coding = skc4 ? kRuleTurtle : kTurtle;
    }
    if (skc4 && format == Format::kBest && (!body || points < kSkc3TryBoth)) {
      // A short update's sections may not follow SKC4's chords (the first has no turtle).
      std::optional<std::string> skc3 = internal::Skc3Body(kind, step, entries, lines, false);
      if (skc3 && (!body || skc3->size() < body->size())) {
        body = std::move(skc3);
        magic = kMagic3;
        coding = kTurtle;
      }
    }
    if (!body || (points < kSkc3TryBoth && format == Format::kBest)) {
      std::optional<std::string> skc2 = CurveBody(kind, step, entries, lines);
      if (skc2 && (!body || skc2->size() < body->size())) {
        body = std::move(skc2);
        magic = kMagic2;
        coding = kCurve;
      }
    }
  } else if (format == Format::kSkc2) {
    body = CurveBody(kind, step, entries, lines);
  }
  if (!body) {
    std::string h = header;
    for (const Entry& e : entries) {
      if (kind == kUpdate) PutVarint(h, e.index);
      PutVarint(h, e.id);
      PutVarint(h, e.version);
    }
    return Assemble(kind, step, h, q);
  }
  std::string out(magic, 4);
  out.push_back(static_cast<char>(kind));
  char sb[8];
  std::memcpy(sb, &step, 8);  // little-endian hosts only (x86-64, aarch64)
  out.append(sb, 8);
  out.push_back(static_cast<char>(coding));
  out += header;
  out += *body;
  return out;
}

/// Decodes the curve coding's body (the rest of the message) into `lines`, whose point counts it
/// reads first and caps by the message size.
Status DecodeCurveBody(std::string_view body, size_t message_size, Kind kind, double step,
                       uint64_t nlines, uint64_t section_count, std::vector<Entry>* entries,
                       std::vector<Polyline2>* lines) {
  internal::RangeDecoder rc(body);
  auto models = std::make_unique<CurveModels>();
  const size_t stride = kind == kPolylineSet ? 1 : 2;
  int64_t index = -1, id = -1, version = 0;
  for (Entry& e : *entries) {
    // Each delta is at most 2^53 in magnitude: no sum below overflows.
    index = kind == kUpdate ? index + 1 + rc.Int(models->index) : index + 1;
    id = id + 1 + rc.Int(models->id);
    version += rc.Int(models->version);
    if (!rc.ok()) return Truncated("section entries");
    if (index < 0 || static_cast<uint64_t>(index) >= section_count) {
      return Outside("contour.section_index", std::to_string(index),
                     std::string("[0, ") + std::to_string(section_count) + ")");
    }
    if (id < 0 || static_cast<uint64_t>(id) > kMaxExactId || version < 0 ||
        static_cast<uint64_t>(version) > kMaxExactId) {
      return Outside("contour.section_id/version",
                     std::to_string(id) + "/" + std::to_string(version), "[0, 2^53)");
    }
    e = {static_cast<uint64_t>(index), static_cast<uint64_t>(id), static_cast<uint64_t>(version)};
  }
  std::vector<uint64_t> counts;
  uint64_t total = 0;
  // An adaptive bit costs at least 1/90 bit, a point two bits: a claim beyond this is a lie that
  // would only make us allocate.
  const uint64_t cap = std::min<uint64_t>(kMaxContourPoints, 65536 + 512 * message_size);
  for (uint64_t j = 0; j < nlines; ++j) {
    const int64_t prev = j >= stride ? static_cast<int64_t>(counts[j - stride]) : 0;
    const int64_t n = prev + rc.Int(models->count);
    if (!rc.ok()) return Truncated("point counts");
    if (n < 0) return InvalidArgument("contour.points=" + std::to_string(n) + " for a polyline");
    total += static_cast<uint64_t>(n);
    if (static_cast<uint64_t>(n) > cap || total > cap) {
      return Outside("contour.points", std::to_string(total),
                     std::string("[0, ") + std::to_string(cap) + "] for a " +
                         std::to_string(message_size) + "-byte message");
    }
    counts.push_back(static_cast<uint64_t>(n));
  }
  lines->assign(nlines, {});
  for (uint64_t j = 0; j < nlines; ++j) {
    if (counts[j] == 0) continue;
    Polyline2& out = (*lines)[j];
    out.resize(counts[j]);
    const Polyline2* ctx = j >= stride ? &(*lines)[j - stride] : nullptr;
    Tail tail;
    if (ctx && !ctx->empty() && rc.Bit(models->join)) tail = TailOf(*ctx);
    if (tail.n == 0) {
      int64_t rx = 0, ry = 0;
      if (ctx && !ctx->empty()) {
        // The context's last point is within 2^52 steps (checked when it was decoded).
        rx = static_cast<int64_t>(std::llround(ctx->back().x / step));
        ry = static_cast<int64_t>(std::llround(ctx->back().y / step));
      }
      // Checked sums: a context point far outside the range rounds to INT64_MIN (the fuzzer's
      // contour target found rx + a delta overflowing).
      int64_t x = 0, y = 0;
      const bool x_overflow = __builtin_add_overflow(rx, rc.Int(models->first), &x);
      const bool y_overflow = __builtin_add_overflow(ry, rc.Int(models->first), &y);
      if (x_overflow || y_overflow || std::abs(static_cast<double>(x)) > kMaxQuantised ||
          std::abs(static_cast<double>(y)) > kMaxQuantised) {
        return InvalidArgument("contour: decoded point outside [-2^52, 2^52] steps");
      }
      tail.Push({static_cast<double>(x) * step, static_cast<double>(y) * step});
    }
    out[0] = tail.p[2];
    const bool closed = out.size() >= 2 && rc.Bit(models->closed);
    const size_t coded = closed ? out.size() - 1 : out.size();
    int64_t prev_a = 0, prev_e = 0;
    double l1 = -1;  // the last frame's step length, once the tail holds three points
    for (size_t k = 1; k < coded; ++k) {
      const Frame f = MakeFrame(tail, tail.n == 3 && l1 > 0 ? l1 : -1);
      l1 = f.l1;
      const int kk = static_cast<int>(std::min<size_t>(k, 2));
      const int64_t a = rc.Int(models->along[AlongContext(kk, prev_a)]);
      const int64_t e = rc.Int(models->across[AcrossContext(kk, prev_e, a)]);
      const double s = f.lp + static_cast<double>(a) * step;
      const Vec2 p = Place(f, s, AcrossAt(f, s) + static_cast<double>(e) * step);
      if (!InPlane(p, step)) {  // also catches NaN
        return InvalidArgument("contour: decoded point outside [-2^52, 2^52] steps");
      }
      // Past the end every bit reads as 0: stop at once rather than run out a claimed count.
      if (!rc.ok()) return Truncated("points");
      prev_a = a;
      prev_e = e;
      tail.Push(p);
      out[k] = p;
    }
    if (closed) out.back() = out.front();
  }
  if (!rc.ok()) return Truncated("curve body");
  if (rc.consumed() != body.size()) {
    return DataLoss("contour: " + std::to_string(body.size() - rc.consumed()) + " trailing bytes");
  }
  return Status::Ok();
}

StatusOr<Parsed> Parse(std::string_view bytes) {
  Reader r{bytes};
  char magic[4];
  uint8_t kind = 0, coding = 0;
  Parsed p;
  if (!r.Bytes(magic, 4) ||
      (std::memcmp(magic, kMagic1, 4) != 0 && std::memcmp(magic, kMagic2, 4) != 0 &&
       std::memcmp(magic, kMagic3, 4) != 0 && std::memcmp(magic, kMagic4, 4) != 0)) {
    return DataLoss("contour: bad magic (want SKC4, SKC3, SKC2 or SKC1)");
  }
  const bool skc4 = magic[3] == '4';
  const bool skc3 = magic[3] == '3' || skc4;  // the same body but for the chord predictor
  const bool skc2 = magic[3] == '2' || skc3;  // the same header
  if (!r.Bytes(&kind, 1)) return Truncated("kind");
  if (kind > kUpdate) return Outside("contour.kind", std::to_string(kind), "[0, 2]");
  p.kind = static_cast<Kind>(kind);
  if (!r.Bytes(&p.step, 8)) return Truncated("step");
  if (!std::isfinite(p.step) || !(p.step > 0)) {
    return Outside("contour.step", FormatNumber(p.step), "(0, inf)");
  }
  if (!r.Bytes(&coding, 1)) return Truncated("coding");
  if (skc4 ? coding != kRuleTurtle
           : skc3 ? coding != kTurtle
           : skc2 ? coding != kCurve
                  : coding > kRans) {
    return InvalidArgument("contour.coding=" + std::to_string(coding) + " outside " +
                           (skc4   ? "[4, 4] for SKC4"
                            : skc3 ? "[3, 3] for SKC3"
                            : skc2 ? "[2, 2] for SKC2"
                                   : "[0, 1] for SKC1"));
  }
  uint64_t nlines = 0;
  if (p.kind == kPolylineSet) {
    if (!r.Varint(&nlines)) return Truncated("polyline count");
    if (nlines > kMaxContourPolylines) {
      return Outside("contour.polylines", std::to_string(nlines),
                     std::string("[0, ") + std::to_string(kMaxContourPolylines) + "]");
    }
  } else {
    uint64_t entries = 0;
    if (!r.Varint(&p.section_count)) return Truncated("section count");
    if (p.section_count > kMaxContourPolylines) {
      return Outside("contour.sections", std::to_string(p.section_count),
                     std::string("[0, ") + std::to_string(kMaxContourPolylines) + "]");
    }
    entries = p.section_count;
    if (p.kind == kUpdate) {
      if (!r.Varint(&p.splice_at) || !r.Varint(&p.removed) || !r.Varint(&p.inserted) ||
          !r.Varint(&entries)) {
        return Truncated("update header");
      }
      if (entries > p.section_count) {
        return Outside("contour.changed", std::to_string(entries),
                       std::string("[0, ") + std::to_string(p.section_count) + "]");
      }
    }
    for (uint64_t i = 0; i < entries && !skc2; ++i) {
      uint64_t idx = i, id = 0, ver = 0;
      if (p.kind == kUpdate && !r.Varint(&idx)) return Truncated("section index");
      if (!r.Varint(&id) || !r.Varint(&ver)) return Truncated("section id");
      if (idx >= p.section_count) {
        return Outside("contour.section_index", std::to_string(idx),
                       std::string("[0, ") + std::to_string(p.section_count) + ")");
      }
      p.index.push_back(idx);
      p.id.push_back(id);
      p.version.push_back(ver);
    }
    nlines = 2 * entries;
  }
  if (coding == kCurve || coding == kTurtle || coding == kRuleTurtle) {
    // Bounded above by the section count (itself capped): no allocation beyond what the header
    // allows.
    std::vector<Entry> ent(p.kind == kPolylineSet ? 0 : nlines / 2);
    if (coding == kTurtle || coding == kRuleTurtle) {
      SCULPT_RETURN_IF_ERROR(internal::DecodeSkc3Body(bytes.substr(r.pos), bytes.size(), p.kind,
                                                      p.step, nlines, p.section_count, &ent,
                                                      &p.lines, coding == kRuleTurtle));
    } else {
      SCULPT_RETURN_IF_ERROR(DecodeCurveBody(bytes.substr(r.pos), bytes.size(), p.kind, p.step,
                                             nlines, p.section_count, &ent, &p.lines));
    }
    for (const Entry& e : ent) {
      p.index.push_back(e.index);
      p.id.push_back(e.id);
      p.version.push_back(e.version);
    }
    return p;
  }
  std::vector<QLine> q(nlines);
  std::vector<std::array<uint64_t, 2>> firsts(nlines);
  uint64_t total = 0, nres = 0;
  for (uint64_t i = 0; i < nlines; ++i) {
    uint64_t n = 0;
    if (!r.Varint(&n)) return Truncated("point count");
    // n is any 64-bit value: a sum that wrapped would pass the cap below (fuzz-found).
    total = n > kMaxContourPoints ? n : total + n;
    // Even entropy-coded, a point costs far more than 1/256 byte: a claim beyond that is a lie
    // that would only make us allocate.
    const uint64_t cap = std::min<uint64_t>(kMaxContourPoints, 65536 + 256 * bytes.size());
    if (total > cap) {
      return Outside("contour.points", std::to_string(total),
                     std::string("[0, ") + std::to_string(cap) + "] for a " +
                         std::to_string(bytes.size()) + "-byte message");
    }
    if (n == 0) continue;
    if (!r.Varint(&firsts[i][0]) || !r.Varint(&firsts[i][1])) return Truncated("first point");
    q[i].resize(n);
    nres += 2 * (n - 1);
  }
  std::vector<uint64_t> res(nres);
  if (coding == kVarint) {
    for (uint64_t& v : res) {
      if (!r.Varint(&v)) return Truncated("residuals");
    }
  } else if (nres > 0) {
    std::vector<uint32_t> sym(nres);
    draco::DecoderBuffer buf;
    buf.Init(bytes.data() + r.pos, bytes.size() - r.pos);
    // The symbol decoder reads the layout of the current bitstream only when told so.
    buf.set_bitstream_version(draco::kDracoPointCloudBitstreamVersion);
    if (!draco::DecodeSymbols(static_cast<uint32_t>(nres), 2, &buf, sym.data())) {
      return DataLoss("contour: residual symbols do not decode");
    }
    r.pos += static_cast<size_t>(buf.decoded_size());
    for (uint64_t i = 0; i < nres; ++i) res[i] = sym[i];
  }
  if (r.pos != bytes.size()) {
    return DataLoss("contour: " + std::to_string(bytes.size() - r.pos) + " trailing bytes");
  }
  size_t next = 0;
  p.lines.resize(nlines);
  for (uint64_t i = 0; i < nlines; ++i) {
    QLine& line = q[i];
    if (line.empty()) continue;
    const QLine* ctx = Context(q, i, p.kind);
    const Q first = PredictFirst(ctx);
    if (!AddBounded(first[0], Unzig(firsts[i][0]), &line[0][0]) ||
        !AddBounded(first[1], Unzig(firsts[i][1]), &line[0][1])) {
      return InvalidArgument("contour: decoded point outside [-2^52, 2^52] steps");
    }
    for (size_t k = 1; k < line.size(); ++k) {
      const Q pr = Predict(line, k, ctx);
      const int64_t dx = Unzig(res[next++]), dy = Unzig(res[next++]);
      if (!AddBounded(pr[0], dx, &line[k][0]) || !AddBounded(pr[1], dy, &line[k][1])) {
        return InvalidArgument("contour: decoded point outside [-2^52, 2^52] steps");
      }
    }
    p.lines[i].reserve(line.size());
    for (const Q& v : line) {
      p.lines[i].push_back({static_cast<double>(v[0]) * p.step, static_cast<double>(v[1]) * p.step});
    }
  }
  return p;
}

StatusOr<double> SkinStep(const Skin& skin, double step) {
  if (step <= 0) return skin.chord_tolerance();
  SCULPT_RETURN_IF_ERROR(CheckRange("step", step, 0, skin.chord_tolerance()));
  return step;
}

}  // namespace

StatusOr<std::string> EncodeContours(const std::vector<Polyline2>& polylines, double step) {
  std::vector<const Polyline2*> ptrs;
  for (const Polyline2& p : polylines) ptrs.push_back(&p);
  std::vector<QLine> q;
  SCULPT_RETURN_IF_ERROR(Quantise(ptrs, step, &q));
  std::string header;
  PutVarint(header, polylines.size());
  return Encode(kPolylineSet, step, header, {}, ptrs, q);
}

namespace {

StatusOr<std::string> ContoursMessage(const std::vector<Polyline2>& polylines, double step,
                                      Format format) {
  std::vector<const Polyline2*> ptrs;
  for (const Polyline2& p : polylines) ptrs.push_back(&p);
  std::vector<QLine> q;
  SCULPT_RETURN_IF_ERROR(Quantise(ptrs, step, &q));
  std::string header;
  PutVarint(header, polylines.size());
  return Encode(kPolylineSet, step, header, {}, ptrs, q, format);
}

}  // namespace

StatusOr<std::string> internal::EncodeContoursSkc2(const std::vector<Polyline2>& polylines,
                                                   double step) {
  return ContoursMessage(polylines, step, Format::kSkc2);
}

StatusOr<std::string> internal::EncodeContoursSkc3(const std::vector<Polyline2>& polylines,
                                                   double step) {
  return ContoursMessage(polylines, step, Format::kSkc3);
}

StatusOr<std::string> internal::EncodeContoursSkc4(const std::vector<Polyline2>& polylines,
                                                   double step) {
  return ContoursMessage(polylines, step, Format::kSkc4);
}

StatusOr<std::string> internal::EncodeContoursSkc1(const std::vector<Polyline2>& polylines,
                                                   double step) {
  std::vector<const Polyline2*> ptrs;
  for (const Polyline2& p : polylines) ptrs.push_back(&p);
  std::vector<QLine> q;
  SCULPT_RETURN_IF_ERROR(Quantise(ptrs, step, &q));
  std::string header;
  PutVarint(header, polylines.size());
  return Assemble(kPolylineSet, step, header, q);
}

StatusOr<std::vector<Polyline2>> DecodeContours(std::string_view bytes) {
  SCULPT_ASSIGN_OR_RETURN(Parsed p, Parse(bytes));
  if (p.kind != kPolylineSet) return InvalidArgument("contour.kind=" + std::to_string(p.kind) + " is a skin message, not a polyline set");
  return std::move(p.lines);
}

namespace {

StatusOr<std::string> SnapshotMessage(const Skin& skin, double step, Format format) {
  SCULPT_ASSIGN_OR_RETURN(const double s, SkinStep(skin, step));
  std::string header;
  PutVarint(header, skin.sections().size());
  std::vector<const Polyline2*> ptrs;
  std::vector<Entry> entries;
  std::vector<bool> fresh;
  for (size_t k = 0; k < skin.sections().size(); ++k) {
    const Section& sec = skin.section(k);
    entries.push_back({k, sec.id, sec.version});
    ptrs.push_back(&sec.plus);
    ptrs.push_back(&sec.minus);
    fresh.insert(fresh.end(), 2, sec.codec_restart);
  }
  std::vector<QLine> q;
  SCULPT_RETURN_IF_ERROR(Quantise(ptrs, s, &q));
  return Encode(kSnapshot, s, header, entries, ptrs, q, format,
                skin.options().sample_for_codec, &fresh);
}

}  // namespace

StatusOr<std::string> EncodeSkinSnapshot(const Skin& skin, double step) {
  return SnapshotMessage(skin, step, Format::kBest);
}

StatusOr<std::string> internal::EncodeSkinSnapshotSkc2(const Skin& skin, double step) {
  return SnapshotMessage(skin, step, Format::kSkc2);
}

StatusOr<std::string> internal::EncodeSkinSnapshotSkc3(const Skin& skin, double step) {
  return SnapshotMessage(skin, step, Format::kSkc3);
}

StatusOr<std::string> internal::EncodeSkinSnapshotSkc4(const Skin& skin, double step) {
  return SnapshotMessage(skin, step, Format::kSkc4);
}

StatusOr<std::string> internal::EncodeSkinSnapshotSkc1(const Skin& skin, double step) {
  return SnapshotMessage(skin, step, Format::kSkc1);
}

StatusOr<std::string> EncodeSkinUpdate(const Skin& skin, const SkinChange& change, double step) {
  SCULPT_ASSIGN_OR_RETURN(const double s, SkinStep(skin, step));
  std::string header;
  PutVarint(header, skin.sections().size());
  PutVarint(header, change.splice_at);
  PutVarint(header, change.removed);
  PutVarint(header, change.inserted);
  PutVarint(header, change.changed.size());
  std::vector<const Polyline2*> ptrs;
  std::vector<Entry> entries;
  std::vector<bool> fresh;
  for (size_t k : change.changed) {
    if (k >= skin.sections().size()) {
      return Outside("change.changed", std::to_string(k),
                     std::string("[0, ") + std::to_string(skin.sections().size()) + ")");
    }
    const Section& sec = skin.section(k);
    entries.push_back({k, sec.id, sec.version});
    ptrs.push_back(&sec.plus);
    ptrs.push_back(&sec.minus);
    fresh.insert(fresh.end(), 2, sec.codec_restart);
  }
  std::vector<QLine> q;
  SCULPT_RETURN_IF_ERROR(Quantise(ptrs, s, &q));
  return Encode(kUpdate, s, header, entries, ptrs, q, Format::kBest,
                skin.options().sample_for_codec, &fresh);
}

Status ContourView::Apply(std::string_view bytes) {
  SCULPT_ASSIGN_OR_RETURN(Parsed p, Parse(bytes));
  if (p.kind == kPolylineSet) return InvalidArgument("contour.kind=0 is a polyline set, not a skin message");
  std::vector<SectionContour> next;
  if (p.kind == kSnapshot) {
    next.resize(p.section_count);
  } else {
    if (p.splice_at > sections_.size() || p.removed > sections_.size() - p.splice_at) {
      return InvalidArgument("contour.splice at " + std::to_string(p.splice_at) + " removing " +
                             std::to_string(p.removed) + " outside the view's " +
                             std::to_string(sections_.size()) + " sections");
    }
    if (p.inserted > p.index.size()) {
      return Outside(
          "contour.inserted", std::to_string(p.inserted),
          std::string("[0, ") + std::to_string(p.index.size()) + "] (the changed sections)");
    }
    if (sections_.size() - p.removed + p.inserted != p.section_count) {
      return InvalidArgument("contour.sections=" + std::to_string(p.section_count) +
                             " does not match the view after the splice");
    }
    next = sections_;
    const auto at = next.begin() + static_cast<std::ptrdiff_t>(p.splice_at);
    next.erase(at, at + static_cast<std::ptrdiff_t>(p.removed));
    next.insert(next.begin() + static_cast<std::ptrdiff_t>(p.splice_at), p.inserted,
                SectionContour{});
  }
  std::vector<bool> filled(next.size(), p.kind == kUpdate);
  if (p.kind == kUpdate) {
    for (uint64_t k = p.splice_at; k < p.splice_at + p.inserted; ++k) filled[k] = false;
  }
  for (size_t e = 0; e < p.index.size(); ++e) {
    SectionContour& s = next[p.index[e]];
    s.id = p.id[e];
    s.version = p.version[e];
    s.plus = std::move(p.lines[2 * e]);
    s.minus = std::move(p.lines[2 * e + 1]);
    filled[p.index[e]] = true;
  }
  for (size_t k = 0; k < filled.size(); ++k) {
    if (!filled[k]) {
      return InvalidArgument("contour: section " + std::to_string(k) + " left without points");
    }
  }
  sections_ = std::move(next);
  step_ = p.step;
  return Status::Ok();
}

Polyline2 ContourView::Chain(int side) const {
  Polyline2 out;
  for (const SectionContour& s : sections_) {
    const Polyline2& p = side > 0 ? s.plus : s.minus;
    if (p.empty()) continue;
    out.insert(out.end(), p.begin() + (out.empty() ? 0 : 1), p.end());
  }
  return out;
}

}  // namespace sculpt::skin
