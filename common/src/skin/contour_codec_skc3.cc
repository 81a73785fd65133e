/// @brief SKC3's body: a turtle in integers (direction as a quantised angle, turn and chord length
/// carried from the last step) placing each point by one along and one across integer, the
/// integers as whole symbols through static per-message rANS tables.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numbers>
#include <optional>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "contour_codec_internal.h"
#include "range_coder.h"
#include "rans_coder.h"
#include "sculpt/skin/contour_codec.h"

namespace sculpt::skin::internal {
namespace {

constexpr double kMaxQuantised = 4503599627370496.0;  // 2^52
constexpr uint64_t kMaxExactId = (1ull << 53) - 1;
constexpr int64_t kMaxChord = int64_t{1} << 40;  // |chord| in steps, and |a|, |e|
constexpr int kAngleBits = 14;                   // directions: 2^14 angles a turn
constexpr int kAngles = 1 << kAngleBits;

/// Contexts: along by |previous along| (0, 1, 2+), and a line's first along without a carried
/// state (then it is the whole chord length); across by |previous across| x |this along|.
constexpr int kAlongStart = 3;
constexpr int kAlongTables = 4;
constexpr int kTables = kAlongTables + 9;

/// |v| of a symbol's integer, capped at 2 (symbols 0, 1-2, 3+ are |v| 0, 1, 2+).
inline int Mag3(int symbol) { return symbol == 0 ? 0 : symbol <= 2 ? 1 : 2; }

/// The decoder's constant tables live in static storage rather than on the heap: their addresses
/// are then link-time constants the point loop rematerialises where it needs them, instead of
/// four more pointers competing for registers with the turtle's and the coders' state (GCC
/// spilled the rANS state and the chord across each point). Each is filled once, by its
/// accessor, which every caller (and FillPointTables) goes through before reading it.
alignas(64) double cos_values[kAngles];

/// The cosine of every angle i * 2 pi / kAngles, from a fixed Taylor series on the first octant
/// and symmetry: + - * only, in an order the JS decoder repeats, so both hold the same doubles.
const double* CosTable() {
  static const double* const table = [] {
    double* t = cos_values;
    constexpr int kQuarter = kAngles / 4, kEighth = kAngles / 8;
    double cc[12], sc[12];  // Taylor coefficients: (-1)^k / (2k)!, (-1)^k / (2k+1)!
    cc[0] = 1;
    sc[0] = 1;
    for (int k = 1; k < 12; ++k) {
      cc[k] = -cc[k - 1] / ((2.0 * k - 1) * (2.0 * k));
      sc[k] = -sc[k - 1] / ((2.0 * k) * (2.0 * k + 1));
    }
    std::vector<double> c(kEighth + 1), s(kEighth + 1);
    const double unit = std::numbers::pi / (kAngles / 2);
    for (int i = 0; i <= kEighth; ++i) {
      const double x = i * unit, x2 = x * x;
      double pc = cc[11], ps = sc[11];
      for (int k = 10; k >= 0; --k) {
        pc = pc * x2 + cc[k];
        ps = ps * x2 + sc[k];
      }
      c[i] = pc;
      s[i] = ps * x;
    }
    for (int i = 0; i < kAngles; ++i) {
      const int q = i / kQuarter, r = i % kQuarter;
      const double v = r <= kEighth ? c[r] : s[kQuarter - r];  // cos of r in [0, pi/2)
      const double w = r == 0 ? 0.0 : (kQuarter - r <= kEighth ? c[kQuarter - r] : s[r]);
      // cos(q pi/2 + r): q=0 cos r, q=1 -sin r, q=2 -cos r, q=3 sin r.
      t[i] = q == 0 ? v : q == 1 ? -w : q == 2 ? -v : w;
    }
    return t;
  }();
  return table;
}

/// floor(kTurnScale / L) for L in [1, kRecipMax]: a turn of e steps across a chord of L steps is
/// about e * kTurn[L] >> 16 angle units (atan(e/L) ~ e/L, 2^14 angles a turn).
constexpr int kRecipMax = 4096;
// round(2^16 * 2^14 / (2 pi) * sqrt(3)/2): an across unit is sqrt(3)/2 of an along unit.
constexpr int64_t kTurnScale = 147996223;
alignas(64) int32_t turn_values[kRecipMax + 1];
const int32_t* TurnTable() {
  static const int32_t* const table = [] {
    int32_t* t = turn_values;
    t[0] = static_cast<int32_t>(kTurnScale);
    for (int l = 1; l <= kRecipMax; ++l) t[l] = static_cast<int32_t>(kTurnScale / l);
    return t;
  }();
  return table;
}

/// The turtle between two points of a line: the direction of the last chord (angle units), the
/// turn from the chord before it, the last chord's length in steps, the last contexts.
struct Turtle {
  int32_t theta = 0, omega = 0;
  int64_t lp = 0;  // the predicted next chord, in lattice spacings
  int64_t l1 = 0;  // the last chord in half spacings (2 chord + the row's parity)
  int actx = 0, mag_e = 0;
  bool valid = false;
};

constexpr int kMaxTurn = kAngles / 8;

/// The next chord: the last one plus its change from the one before, that change limited to
/// about 5 % of the chord (13/256; spacing follows curvature, which changes slowly, but jumps
/// where the sampler's pieces meet).
[[gnu::always_inline]] inline int64_t NextChord(int64_t len, int64_t l1) {
  // min / max rather than a conditional and std::clamp, which GCC made branches of: the limit
  // binds where the data says, a misprediction a few points apart.
  const int64_t m = (std::max<int64_t>(len, 0) * 13) >> 8;
  return len + std::min(std::max(len - l1, -m), m);
}

/// SKC4's next chord, from the chord rule: a chord of h half spacings that turned by omega angle
/// units lies on a curve of curvature about omega / h, on which the chord whose sagitta is
/// kRuleTarget of the step (the skin's sampler puts the chord tolerance there) is sqrt(kChordRule
/// h / |omega|) half spacings: kChordRule = 8 kRuleTarget (1 / kHalfAlong') 2^14 / (2 pi), with
/// kHalfAlong' = sqrt(3/2)/2 the half spacing in steps. The target is well under 1 because the
/// turn carries the lattice's rounding (about 10 %): on the benchmark's skin 0.59 gave the fewest
/// bytes with the fewest points among targets giving about that many bytes (0.35-0.53: within
/// 2 % of the bytes, 12-23 % more points; 0.75: 6 % more bytes, 0.88: 19 %). Limited to a quarter of the last chord
/// either way (plus 2 half spacings, so that a short chord can grow); in lattice spacings.
/// + - * / and sqrt in doubles, all exactly rounded, so the JS decoder computes the same.
constexpr double kChordRule = 20000.0;              // kRuleTarget = 0.587
constexpr int64_t kRuleMaxHalf = int64_t{1} << 20;  // h above this counts as this in the rule

/// RuleChord as the format defines it (and the JS decoder computes it): the doubles above, then
/// the limits. The decoder's loop takes RuleChord's shorter road and comes here only where the
/// two could differ.
[[gnu::noinline]] int64_t RuleChordDefinition(int64_t h, int32_t omega) {
  if (h <= 0) return h >> 1;  // floor(h / 2)
  const int64_t lo = h - (h >> 2), hi = h + (h >> 2) + 2;
  const int64_t w = omega < 0 ? -static_cast<int64_t>(omega) : omega;
  int64_t g = hi;
  if (w > 0) {
    const double c = std::sqrt(kChordRule * static_cast<double>(std::min(h, kRuleMaxHalf)) /
                               static_cast<double>(w));
    g = c < static_cast<double>(lo)   ? lo
        : c > static_cast<double>(hi) ? hi
                                      : static_cast<int64_t>(c);
  }
  return g >> 1;
}

/// sqrt(kChordRule / w) for |omega| = w in [1, kMaxTurn]; 0 for w = 0 (RuleChord sets that aside).
alignas(64) double root_values[kMaxTurn + 1];
const double* RuleRootTable() {
  static const double* const table = [] {
    double* t = root_values;
    t[0] = 0;
    for (int w = 1; w <= kMaxTurn; ++w) t[w] = std::sqrt(kChordRule / w);
    return t;
  }();
  return table;
}

/// RuleChordDefinition, bit for bit, with a shorter dependency chain: sqrt(h) times a table entry
/// in place of a division and a square root after it (the chord rule is the loop-carried chain of
/// SKC4's decoder, h and omega come from the point just decoded). The definition's
/// c = sqrt(kChordRule h / w) and this one differ by a few ulps: both within 2^-33 of the exact
/// value, since c < 2^18 (h <= 2^20, w >= 1). So where this c is more than 2^-20 from an integer,
/// both floor to the same integer, and the limits (integers) act on the floors alike. Where it is
/// that close (about one chord in 500 000, or a crafted stream), the definition decides.
[[gnu::always_inline]] inline int64_t RuleChord(int64_t h, int32_t omega, const double* root) {
  if (h <= 0) [[unlikely]]
    return h >> 1;
  const int64_t lo = h - (h >> 2), hi = h + (h >> 2) + 2;
  const int32_t w = omega < 0 ? -omega : omega;
  const double c = std::sqrt(static_cast<double>(std::min(h, kRuleMaxHalf))) * root[w];
  const int64_t n = static_cast<int64_t>(c);  // c >= 0: the floor
  const double f = c - static_cast<double>(n);
  constexpr double kNearInteger = 0x1p-20;
  if ((f < kNearInteger || f > 1 - kNearInteger) && w != 0) [[unlikely]]
    return RuleChordDefinition(h, omega);
  return (w == 0 ? hi : std::clamp(n, lo, hi)) >> 1;
}

/// The turn a point makes off the predicted direction, in angle units, and the turtle after it;
/// `rule`: SKC4's chord rule predicts the next chord, else SKC3's trend.
[[gnu::always_inline]] inline void Advance(Turtle& t, int32_t th, int64_t len, int64_t e,
                                           const int32_t* turn, bool rule) {
  const int64_t lc = std::clamp<int64_t>(len, 1, kRecipMax);
  const int64_t ec = std::clamp<int64_t>(e, -lc, lc);
  const int32_t d = static_cast<int32_t>((ec * turn[lc]) >> 16);
  t.theta = (th + d) & (kAngles - 1);
  t.omega = std::clamp<int32_t>(t.omega + d, -kMaxTurn, kMaxTurn);
  const int64_t h = 2 * len + (e & 1);
  t.lp = rule ? RuleChord(h, t.omega, RuleRootTable()) : NextChord(h, t.l1) >> 1;
  t.l1 = h;
}

bool InPlaneSteps(Vec2 p, double step) {
  return std::abs(p.x) <= kMaxQuantised * step && std::abs(p.y) <= kMaxQuantised * step;
}

/// The hexagonal lattice of offsets in the frame: rows `e` across, kAcross apart, points along
/// each row kAlong apart, odd rows shifted by half of that. Its covering radius is step/sqrt(2)
/// times (1 - 2^-20) (the margin absorbs rounding): the same bound as a square lattice of side
/// step, with 1.3 times the area per point (0.38 bits a point less).
constexpr double kHalfAlong = 0.6123718516919304;  // sqrt(3/2)/2 (1 - 2^-20)
constexpr double kAcross = 1.060659160255457;      // 1.5/sqrt(2) (1 - 2^-20)

/// The decoded point from the previous one, the frame angle, the chord (lattice points along)
/// and the row across; `hs` = step * kHalfAlong, `vs` = step * kAcross.
[[gnu::always_inline]] inline Vec2 Place(Vec2 p, const double* cos_table, int32_t th, int64_t len,
                                         int64_t e, double hs, double vs) {
  const double ux = cos_table[th], uy = cos_table[(th - kAngles / 4) & (kAngles - 1)];
  const double ls = static_cast<double>(2 * len + (e & 1)) * hs, es = static_cast<double>(e) * vs;
  return {p.x + (ls * ux - es * uy), p.y + (ls * uy + es * ux)};
}

/// The lattice point the decoder will place nearest to `target` (among the two rows around it and
/// their neighbours), from the decoded point p in the frame of angle th; false where none is
/// within the bound (or within the plane).
bool PlaceNearest(Vec2 p, const double* cos_table, int32_t th, Vec2 target, double step,
                  int64_t* len, int64_t* e, Vec2* q) {
  const double bound2 = step * step / 2;
  const double hs = step * kHalfAlong, vs = step * kAcross;
  const double ux = cos_table[th], uy = cos_table[(th - kAngles / 4) & (kAngles - 1)];
  const double dx = target.x - p.x, dy = target.y - p.y;
  const double ta = (dx * ux + dy * uy) / (2 * hs), te = (dy * ux - dx * uy) / vs;
  if (!(std::abs(ta) < static_cast<double>(kMaxChord)) ||
      !(std::abs(te) < static_cast<double>(kMaxChord))) {
    return false;
  }
  const int64_t e0 = static_cast<int64_t>(std::floor(te));
  bool placed = false;
  double best = bound2;
  for (int64_t ec = e0 - 1; ec <= e0 + 2; ++ec) {
    const int64_t l0 = std::llround(ta - 0.5 * static_cast<double>(ec & 1));
    for (int64_t lc = l0 - 1; lc <= l0 + 1; ++lc) {
      const Vec2 c = Place(p, cos_table, th, lc, ec, hs, vs);
      const Vec2 d = c - target;
      const double d2 = d.x * d.x + d.y * d.y;
      if (d2 <= best && InPlaneSteps(c, step)) {
        best = d2;
        *len = lc;
        *e = ec;
        *q = c;
        placed = true;
      }
    }
  }
  return placed && std::abs(*len) <= kMaxChord;
}

/// What the decoder needs of a symbol: its zigzag value without the extra bits, how many extra
/// bits follow and their mask. One more entry for kRansNoSymbol (all zero).
struct SymbolInfo {
  uint64_t base, mask;
  int bits;
};
constexpr std::array<SymbolInfo, kRansAlphabet + 1> kSymbolInfos = [] {
  std::array<SymbolInfo, kRansAlphabet + 1> t{};
  for (int s = 0; s < kRansAlphabet; ++s) {
    const int bits = TokenExtraBits(s);
    t[s] = {s < kTokenDirect
                ? static_cast<uint64_t>(s)
                : (uint64_t{2} | static_cast<uint64_t>((s - kTokenDirect) & 1)) << bits,
            (uint64_t{1} << bits) - 1, bits};
  }
  t[kRansAlphabet] = {0, 0, 0};
  return t;
}();

/// Mag3 of every symbol, the tag of its rANS slots.
const uint8_t* MagnitudeTags() {
  static const std::array<uint8_t, kRansAlphabet> table = [] {
    std::array<uint8_t, kRansAlphabet> t{};
    for (int s = 0; s < kRansAlphabet; ++s) t[s] = static_cast<uint8_t>(Mag3(s));
    return t;
  }();
  return table.data();
}

inline int64_t Unzig(uint64_t zz) {
  return static_cast<int64_t>(zz >> 1) ^ -static_cast<int64_t>(zz & 1);
}

/// The mark DecodeSkc3Body adds to every slot of an empty table (one whose every slot decodes
/// kRansNoSymbol): the point loop ORs the slots it decodes and fails the line where the mark
/// shows. The mark sits in the frequency's bits (an empty table's frequency is otherwise
/// kRansScale, which leaves the state as it was): past a marked slot the state is garbage, which
/// no longer matters, the line being refused. No slot of a table with symbols has it (frequencies
/// are at most kRansScale = 2^10, bits 19-29).
constexpr RansSlot kEmptySlot = RansSlot{1} << 31;
static_assert(kSlotFreqShift + kRansScaleBits + 1 <= 31);

/// The largest |x| and |y| of the points placed so far and `p`, both at once: one AND and one
/// maximum of a pair where SSE2 has them (GCC kept two scalar maxima and their shuffles). A NaN
/// coordinate leaves the running maximum as it was, as std::max(reach, |p|) does.
struct Reach {
#if defined(__SSE2__)
  __m128d v = _mm_setzero_pd();
  [[gnu::always_inline]] void Add(Vec2 p) {
    const __m128d abs_mask = _mm_castsi128_pd(_mm_set1_epi64x(0x7fffffffffffffff));
    v = _mm_max_pd(_mm_and_pd(_mm_set_pd(p.y, p.x), abs_mask), v);  // (|p| > v) ? |p| : v
  }
  bool Within(double lim) const { return _mm_movemask_pd(_mm_cmple_pd(v, _mm_set1_pd(lim))) == 3; }
#else
  Vec2 v{0, 0};
  void Add(Vec2 p) { v = {std::max(v.x, std::abs(p.x)), std::max(v.y, std::abs(p.y))}; }
  bool Within(double lim) const { return v.x <= lim && v.y <= lim; }
#endif
};

/// Fills the point loop's constant tables (each accessor fills its own once), which the loop
/// then reads by name: called once a message, not once a line (each accessor checks its guard).
void FillPointTables() {
  CosTable();
  TurnTable();
  RuleRootTable();
}

/// What SKC3's point loop reads and does not change within a message (gathered once: a line is
/// about 20 points).
struct PointContext {
  const RansSlot* tables;  // the message's kTables symbol tables
  double hs, vs;           // step * kHalfAlong, step * kAcross
  double lim;              // the plane: |x|, |y| <= lim
};

/// SKC3's point loop: the next `n` points of a line after `p` into `out`, each from an along and
/// an across integer, advancing the turtle `t` (direction, turn, chords and the contexts of the
/// next symbols; `kRule`: SKC4's chord rule, else SKC3's trend). `bad` is set where a symbol comes
/// from an empty table, a chord leaves [-kMaxChord, kMaxChord] or a point the plane. `kChecked`
/// false only where the stream holds a word for every symbol still to decode.
/// Returns the number of points placed: checked, the loop stops at the next multiple of 64 points
/// once the stream has run out or a point is bad (a claimed count may be far beyond the bytes;
/// past the end the stream reads zeros).
template <bool kChecked, bool kRule>
size_t DecodePoints(const PointContext& c, RansDecoder* rans_at, BitReader* raw_at, size_t n,
                    Vec2 p, Turtle* t, bool* bad, Vec2* out) {
  // Copies whose address does not escape, so that their state lives in registers (the stores to
  // `out` would otherwise have them written back every point).
  RansDecoder rans = *rans_at;
  BitReader raw = *raw_at;
  const RansSlot* tables = c.tables;
  // The static tables by name (FillPointTables filled them): their addresses are constants.
  const SymbolInfo* info = kSymbolInfos.data();
  const double* cos_table = cos_values;
  const int32_t* turn = turn_values;
  const double* root = root_values;
  const double hs = c.hs, vs = c.vs, lim = c.lim;
  int32_t theta = t->theta, omega = t->omega;
  int64_t lp = t->lp, l1 = t->l1;
  int actx = t->actx, mag_e = t->mag_e;
  // Every slot decoded, ORed, and bit 31 for a chord out of range: a bad symbol or chord shows
  // as kEmptySlot, one OR a symbol rather than two compares and a flag (which GCC kept on the
  // stack).
  uint32_t seen = 0;
  // The largest |x| and |y| placed: two maxima a point rather than two compares. A NaN point
  // makes every point after it NaN (each is the last plus a step), so the last point shows it.
  Reach reach;
  // A moving pointer rather than an index and a count: one register fewer in the loop (GCC kept
  // the index on the stack).
  Vec2* o = out;
  Vec2* const end = out + n;
  while (o != end) {
    // Branch-free: the symbols are what the data makes them. kRansNoSymbol (a slot of an empty
    // table, marked kEmptySlot) reads as 0 and fails the line.
    // The slots carry each symbol's magnitude class as their tag: the next table is picked
    // without waiting for a second lookup.
    const RansSlot* atable = tables + static_cast<size_t>(actx) * kRansScale;
    const RansSlot as = kChecked ? rans.DecodeSlot(atable, 0) : rans.DecodeSlotUnchecked(atable, 0);
    const uint32_t asym = SlotSymbol(as);
    const SymbolInfo& ai = info[asym];
    const RansSlot* etable =
        tables + static_cast<size_t>(kAlongTables + 3 * mag_e + SlotTag(as)) * kRansScale;
    const RansSlot es = kChecked ? rans.DecodeSlot(etable, 1) : rans.DecodeSlotUnchecked(etable, 1);
    const uint32_t esym = SlotSymbol(es);
    const SymbolInfo& ei = info[esym];
    uint64_t ax, ex;  // the raw bits of both symbols, a's first
    raw.Get2(ai.bits, ai.mask, ei.bits, ei.mask, &ax, &ex);
    const int64_t a = Unzig(ai.base + ax);
    const int64_t e = Unzig(ei.base + ex);
    const int32_t th = (theta + omega) & (kAngles - 1);
    const int64_t len = lp + a;
    p = Place(p, cos_table, th, len, e, hs, vs);
    const bool chord_out = static_cast<uint64_t>(len + kMaxChord) > uint64_t{2 * kMaxChord};
    seen |= as | es | (static_cast<uint32_t>(chord_out) << 31);
    reach.Add(p);
    const int64_t lc = std::clamp<int64_t>(len, 1, kRecipMax);
    const int64_t ec = std::clamp<int64_t>(e, -lc, lc);
    const int32_t d = static_cast<int32_t>((ec * turn[lc]) >> 16);
    theta = (th + d) & (kAngles - 1);
    omega = std::clamp<int32_t>(omega + d, -kMaxTurn, kMaxTurn);
    const int64_t h = 2 * len + (e & 1);
    if constexpr (kRule) {
      lp = RuleChord(h, omega, root);
    } else {
      lp = NextChord(h, l1) >> 1;
    }
    l1 = h;
    actx = static_cast<int>(SlotTag(as));
    mag_e = static_cast<int>(SlotTag(es));
    *o++ = p;
    // o - out: the points placed by this call (out starts at the line's second point).
    if (kChecked && ((o - out) & 63) == 0 && ((seen & kEmptySlot) || rans.overrun())) break;
  }
  bool fail = (seen & kEmptySlot) != 0;
  const size_t k = static_cast<size_t>(o - out);
  if (k > 0) {
    fail |= !reach.Within(lim) | !(std::abs(p.x) <= lim) | !(std::abs(p.y) <= lim);
  }
  t->theta = theta;
  t->omega = omega;
  t->lp = lp;
  t->l1 = l1;
  t->actx = actx;
  t->mag_e = mag_e;
  *bad |= fail;
  *rans_at = rans;
  *raw_at = raw;
  return k;
}

bool StepIndex(double v, double step, int64_t* out) {
  const double x = v / step;
  if (!(std::abs(x) <= kMaxQuantised)) return false;
  *out = static_cast<int64_t>(std::llround(x));
  return true;
}

/// The range-coded side information's models.
struct SideModels {
  IntModel index, id, version, count, first, nsym, freq;
  BitModel join, closed;
};

size_t StrideOf(int kind) { return kind == 0 ? 1 : 2; }

void PutVarint(std::string& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

bool GetVarint(std::string_view in, size_t* pos, uint64_t* v) {
  uint64_t r = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (*pos >= in.size()) return false;
    const uint8_t b = static_cast<uint8_t>(in[(*pos)++]);
    r |= static_cast<uint64_t>(b & 0x7f) << shift;
    if (!(b & 0x80)) {
      *v = r;
      return true;
    }
  }
  return false;
}

}  // namespace

std::optional<std::string> Skc3Body(int kind, double step, const std::vector<SectionEntry>& entries,
                                    const std::vector<const Polyline2*>& lines, bool skc4,
                                    const std::vector<bool>* fresh) {
  const double bound2 = step * step / 2;
  const double* cos_table = CosTable();
  const int32_t* turn = TurnTable();
  const size_t stride = StrideOf(kind);
  // Per line: join, first point delta, closed, start angle (when it has no carried turtle).
  struct LineSide {
    bool has_ctx = false, join = false, closed = false, needs_theta = false;
    int64_t fx = 0, fy = 0;
    int32_t theta0 = 0;
  };
  std::vector<LineSide> side(lines.size());
  struct Sym {
    uint8_t table, symbol;
  };
  std::vector<Sym> syms;
  BitWriter raw;
  std::vector<std::array<uint64_t, kRansAlphabet>> counts(kTables);
  for (auto& c : counts) c.fill(0);
  std::vector<Polyline2> decoded(lines.size());
  std::vector<Turtle> end_state(lines.size());
  auto put = [&](int table, int64_t v) {
    const Token t = MakeToken(v);
    syms.push_back({static_cast<uint8_t>(table), static_cast<uint8_t>(t.symbol)});
    ++counts[table][t.symbol];
    raw.Put(t.extra, t.extra_bits);
    return t.symbol;
  };
  for (size_t j = 0; j < lines.size(); ++j) {
    const Polyline2& in = *lines[j];
    if (in.empty()) continue;
    LineSide& ls = side[j];
    Polyline2& out = decoded[j];
    out.reserve(in.size());
    const Polyline2* ctx = j >= stride ? &decoded[j - stride] : nullptr;
    Turtle t;
    Vec2 p;
    ls.has_ctx = ctx && !ctx->empty();
    if (ls.has_ctx && !(fresh && (*fresh)[j])) {
      const Vec2 d = in[0] - ctx->back();
      ls.join = d.x * d.x + d.y * d.y <= bound2;
    }
    if (ls.join) {
      p = ctx->back();
      t = end_state[j - stride];
    } else {
      int64_t rx = 0, ry = 0, x = 0, y = 0;
      if (ls.has_ctx &&
          (!StepIndex(ctx->back().x, step, &rx) || !StepIndex(ctx->back().y, step, &ry))) {
        return std::nullopt;
      }
      if (!StepIndex(in[0].x, step, &x) || !StepIndex(in[0].y, step, &y)) return std::nullopt;
      ls.fx = x - rx;
      ls.fy = y - ry;
      if (std::abs(ls.fx) > static_cast<int64_t>(kMaxCodedMagnitude) ||
          std::abs(ls.fy) > static_cast<int64_t>(kMaxCodedMagnitude)) {
        return std::nullopt;
      }
      p = {static_cast<double>(x) * step, static_cast<double>(y) * step};
      const Vec2 d = p - in[0];
      if (!(d.x * d.x + d.y * d.y <= bound2)) return std::nullopt;
    }
    out.push_back(p);
    ls.closed = in.size() >= 2 && in.back() == in.front();
    const size_t coded = ls.closed ? in.size() - 1 : in.size();
    if (coded >= 2 && !t.valid) {
      ls.needs_theta = true;
      const Vec2 d = in[1] - p;
      const double a = std::atan2(d.y, d.x) / (2 * std::numbers::pi) * kAngles;
      if (!std::isfinite(a)) return std::nullopt;
      ls.theta0 = static_cast<int32_t>(std::llround(a)) & (kAngles - 1);
      t = Turtle{};
      t.theta = ls.theta0;
      t.actx = kAlongStart;
      t.valid = true;
    }
    for (size_t k = 1; k < coded; ++k) {
      const int32_t th = (t.theta + t.omega) & (kAngles - 1);
      int64_t len = 0, e = 0;
      Vec2 q;
      if (!PlaceNearest(p, cos_table, th, in[k], step, &len, &e, &q)) return std::nullopt;
      const int64_t a = len - t.lp;
      if (std::abs(a) > kMaxTokenMagnitude) return std::nullopt;
      const int asym = put(t.actx, a);
      const int esym = put(kAlongTables + 3 * t.mag_e + Mag3(asym), e);
      Advance(t, th, len, e, turn, skc4);
      t.actx = Mag3(asym);
      t.mag_e = Mag3(esym);
      p = q;
      out.push_back(p);
    }
    end_state[j] = t;
    if (ls.closed) out.push_back(out.front());
  }

  // The side information, range coded: entries, counts, tables, then per line.
  RangeEncoder rc;
  auto m = std::make_unique<SideModels>();
  SectionEntry prev{static_cast<uint64_t>(-1), static_cast<uint64_t>(-1), 0};
  for (const SectionEntry& e : entries) {
    if (e.id > kMaxExactId || e.version > kMaxExactId) return std::nullopt;
    if (kind == 2) rc.Int(m->index, static_cast<int64_t>(e.index - (prev.index + 1)));
    rc.Int(m->id, static_cast<int64_t>(e.id) - static_cast<int64_t>(prev.id + 1));
    rc.Int(m->version, static_cast<int64_t>(e.version) - static_cast<int64_t>(prev.version));
    prev = e;
  }
  for (size_t j = 0; j < lines.size(); ++j) {
    const size_t before = j >= stride ? lines[j - stride]->size() : 0;
    rc.Int(m->count, static_cast<int64_t>(lines[j]->size()) - static_cast<int64_t>(before));
  }
  std::vector<std::vector<uint32_t>> freq(kTables);
  for (int t = 0; t < kTables; ++t) {
    std::vector<uint64_t> c(counts[t].begin(), counts[t].end());
    while (!c.empty() && c.back() == 0) c.pop_back();
    freq[t] = NormaliseCounts(c);
    rc.Int(m->nsym, static_cast<int64_t>(freq[t].size()));
    for (uint32_t f : freq[t]) rc.Int(m->freq, f);
  }
  for (size_t j = 0; j < lines.size(); ++j) {
    const LineSide& ls = side[j];
    if (lines[j]->empty()) continue;
    if (ls.has_ctx) rc.Bit(m->join, ls.join);
    if (!ls.join) {
      rc.Int(m->first, ls.fx);
      rc.Int(m->first, ls.fy);
    }
    if (lines[j]->size() >= 2) rc.Bit(m->closed, ls.closed);
    if (ls.needs_theta) rc.Raw(static_cast<uint64_t>(ls.theta0), kAngleBits);
  }
  const std::string side_bytes = rc.Finish();

  RansEncoder rans;
  std::vector<std::vector<uint32_t>> start(kTables);
  for (int t = 0; t < kTables; ++t) {
    start[t].assign(freq[t].size() + 1, 0);
    for (size_t i = 0; i < freq[t].size(); ++i) start[t][i + 1] = start[t][i] + freq[t][i];
  }
  for (size_t i = 0; i < syms.size(); ++i) {
    const Sym& s = syms[i];
    rans.Put(freq[s.table][s.symbol], start[s.table][s.symbol], s.table < kAlongTables ? 0 : 1);
  }
  const std::string rans_bytes = rans.Finish();
  std::string body;
  PutVarint(body, side_bytes.size());
  body += side_bytes;
  PutVarint(body, rans_bytes.size());
  body += rans_bytes;
  body += raw.Finish();
  return body;
}

Status DecodeSkc3Body(std::string_view body, size_t message_size, int kind, double step,
                      uint64_t nlines, uint64_t section_count, std::vector<SectionEntry>* entries,
                      std::vector<Polyline2>* lines, bool skc4) {
  auto truncated = [](const char* what) {
    return DataLoss(std::string("contour: truncated ") + what);
  };
  size_t pos = 0;
  uint64_t side_len = 0, rans_len = 0;
  if (!GetVarint(body, &pos, &side_len) || side_len > body.size() - pos) {
    return truncated("SKC3 side information");
  }
  const std::string_view side_bytes = body.substr(pos, side_len);
  pos += side_len;
  if (!GetVarint(body, &pos, &rans_len) || rans_len > body.size() - pos) {
    return truncated("SKC3 symbols");
  }
  const std::string_view rans_bytes = body.substr(pos, rans_len);
  const std::string_view raw_bytes = body.substr(pos + rans_len);

  RangeDecoder rc(side_bytes);
  auto m = std::make_unique<SideModels>();
  const size_t stride = StrideOf(kind);
  int64_t index = -1, id = -1, version = 0;
  for (SectionEntry& e : *entries) {
    // Each delta is at most 2^53 in magnitude: no sum below overflows.
    index = kind == 2 ? index + 1 + rc.Int(m->index) : index + 1;
    id = id + 1 + rc.Int(m->id);
    version += rc.Int(m->version);
    if (!rc.ok()) return truncated("section entries");
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
  counts.reserve(nlines);
  uint64_t total = 0;
  // A point costs at least its two symbols' share of a byte; a claim beyond this cap is a lie
  // that would only make us allocate.
  const uint64_t cap = std::min<uint64_t>(kMaxContourPoints, 65536 + 512 * message_size);
  for (uint64_t j = 0; j < nlines; ++j) {
    const int64_t before = j >= stride ? static_cast<int64_t>(counts[j - stride]) : 0;
    const int64_t n = before + rc.Int(m->count);
    if (!rc.ok()) return truncated("point counts");
    if (n < 0) return InvalidArgument("contour.points=" + std::to_string(n) + " for a polyline");
    total += static_cast<uint64_t>(n);
    if (static_cast<uint64_t>(n) > cap || total > cap) {
      return Outside("contour.points", std::to_string(total),
                     std::string("[0, ") + std::to_string(cap) + "] for a " +
                         std::to_string(message_size) + "-byte message");
    }
    counts.push_back(static_cast<uint64_t>(n));
  }
  std::vector<RansSlot> slots(static_cast<size_t>(kTables) * kRansScale);
  for (int t = 0; t < kTables; ++t) {
    const int64_t nsym = rc.Int(m->nsym);
    if (nsym < 0 || nsym > kRansAlphabet) {
      return Outside("contour.table_symbols", std::to_string(nsym),
                     std::string("[0, ") + std::to_string(kRansAlphabet) + "]");
    }
    std::vector<uint32_t> f(static_cast<size_t>(nsym));
    for (uint32_t& v : f) {
      const int64_t x = rc.Int(m->freq);
      if (x < 0 || x > static_cast<int64_t>(kRansScale)) {
        return Outside("contour.table_frequency", std::to_string(x),
                       std::string("[0, ") + std::to_string(kRansScale) + "]");
      }
      v = static_cast<uint32_t>(x);
    }
    if (!rc.ok()) return truncated("symbol tables");
    RansSlot* table = &slots[static_cast<size_t>(t) * kRansScale];
    if (!BuildRansSlots(f, table, MagnitudeTags())) {
      return InvalidArgument("contour: symbol table " + std::to_string(t) +
                             " frequencies do not sum to " + std::to_string(kRansScale));
    }
    if (SlotSymbol(table[0]) == kRansNoSymbol) {
      for (uint32_t i = 0; i < kRansScale; ++i) table[i] |= kEmptySlot;
    }
  }
  struct LineSide {
    bool join = false, closed = false, needs_theta = false;
    int64_t fx = 0, fy = 0;
    int32_t theta0 = 0;
  };
  std::vector<LineSide> side(nlines);
  {
    // Which lines end with a turtle (for the next line of their side to carry): one that placed
    // a point by it, or carried one through.
    std::vector<uint8_t> valid(nlines, 0);
    for (uint64_t j = 0; j < nlines; ++j) {
      if (counts[j] == 0) continue;
      LineSide& ls = side[j];
      const bool has_ctx = j >= stride && counts[j - stride] > 0;
      if (has_ctx) ls.join = rc.Bit(m->join);
      if (!ls.join) {
        ls.fx = rc.Int(m->first);
        ls.fy = rc.Int(m->first);
      }
      if (counts[j] >= 2) ls.closed = rc.Bit(m->closed);
      const uint64_t coded = ls.closed ? counts[j] - 1 : counts[j];
      const bool carried = ls.join && valid[j - stride];
      if (coded >= 2 && !carried) {
        ls.needs_theta = true;
        ls.theta0 = static_cast<int32_t>(rc.Raw(kAngleBits));
      }
      valid[j] = carried || coded >= 2;
      if (!rc.ok()) return truncated("line starts");
    }
  }
  if (rc.consumed() != side_bytes.size()) {
    return DataLoss("contour: " + std::to_string(side_bytes.size() - rc.consumed()) +
                    " trailing bytes in the SKC3 side information");
  }

  RansDecoder rans(rans_bytes);
  BitReader raw(raw_bytes);
  FillPointTables();
  const PointContext context{slots.data(), step * kHalfAlong, step * kAcross, kMaxQuantised * step};
  lines->assign(nlines, {});
  // Each line is decoded into `scratch` and copied into its polyline once whole (one memcpy):
  // resizing the polyline first would zero-fill it (Vec2's members have initialisers), a store
  // loop as long as the decoding's own stores. Uninitialised storage for the longest line, which
  // the counts' cap above bounds as it bounded the polylines' allocations.
  const uint64_t longest = counts.empty() ? 0 : *std::max_element(counts.begin(), counts.end());
  const std::unique_ptr<std::byte[]> scratch_bytes(new std::byte[longest * sizeof(Vec2)]);
  Vec2* const scratch = reinterpret_cast<Vec2*>(scratch_bytes.get());
  Turtle carried[2];  // the end turtle of the last line of each side (index j % stride)
  for (uint64_t j = 0; j < nlines; ++j) {
    Turtle& t = carried[j % stride];
    if (counts[j] == 0) {
      t = Turtle{};
      continue;
    }
    const LineSide& ls = side[j];
    const size_t count = counts[j];
    Vec2 p;
    if (ls.join) {
      p = (*lines)[j - stride].back();
    } else {
      t = Turtle{};
      int64_t rx = 0, ry = 0;
      if (j >= stride && !(*lines)[j - stride].empty()) {
        // The context's last point is within 2^52 steps (checked when it was decoded).
        rx = static_cast<int64_t>(std::llround((*lines)[j - stride].back().x / step));
        ry = static_cast<int64_t>(std::llround((*lines)[j - stride].back().y / step));
      }
      const int64_t x = rx + ls.fx, y = ry + ls.fy;
      if (std::abs(static_cast<double>(x)) > kMaxQuantised ||
          std::abs(static_cast<double>(y)) > kMaxQuantised) {
        return InvalidArgument("contour: decoded point outside [-2^52, 2^52] steps");
      }
      p = {static_cast<double>(x) * step, static_cast<double>(y) * step};
    }
    if (ls.needs_theta) {
      t = Turtle{};
      t.theta = ls.theta0;
      t.actx = kAlongStart;
      t.valid = true;
    }
    scratch[0] = p;
    const size_t coded = ls.closed ? count - 1 : count;
    if (coded >= 2) {
      const size_t n = coded - 1;
      bool bad = false;
      // Two symbols a point, at most a word each: unchecked where the words are there.
      if (rans.words_left() / 2 >= n) {
        (skc4 ? DecodePoints<false, true> : DecodePoints<false, false>)(context, &rans, &raw, n, p,
                                                                        &t, &bad, scratch + 1);
      } else {
        (skc4 ? DecodePoints<true, true> : DecodePoints<true, false>)(context, &rans, &raw, n, p,
                                                                      &t, &bad, scratch + 1);
      }
      if (bad) {
        return InvalidArgument(
            "contour: decoded point outside [-2^52, 2^52] steps, or a "
            "symbol from an empty table");
      }
      if (rans.overrun()) return truncated("points");
    }
    if (ls.closed) scratch[count - 1] = scratch[0];
    (*lines)[j].assign(scratch, scratch + count);
  }
  if (!rans.ok()) return DataLoss("contour: the SKC3 symbol stream does not end where it began");
  if (!raw.ok()) return DataLoss("contour: the SKC3 raw bits do not end with the last symbol");
  return Status::Ok();
}

namespace {

Turtle FromCursor(const CodecCursor& c) {
  Turtle t;
  t.theta = c.theta;
  t.omega = c.omega;
  t.lp = c.lp;
  t.l1 = c.l1;
  t.actx = c.actx;
  t.mag_e = c.mag_e;
  t.valid = c.valid;
  return t;
}

void ToCursor(const Turtle& t, Vec2 p, CodecCursor* c) {
  c->theta = t.theta;
  c->omega = t.omega;
  c->lp = t.lp;
  c->l1 = t.l1;
  c->actx = t.actx;
  c->mag_e = t.mag_e;
  c->valid = t.valid;
  c->p = p;
  c->has_point = true;
}

}  // namespace

int64_t Skc4ChordRule(int64_t h, int32_t omega) { return RuleChord(h, omega, RuleRootTable()); }

int64_t Skc4ChordRuleDefinition(int64_t h, int32_t omega) { return RuleChordDefinition(h, omega); }

void Skc4Predict(const CodecCursor& c, double step, Vec2* u, double* along_even,
                 double* along_odd) {
  const double* cos_table = CosTable();
  const int32_t th = (c.theta + c.omega) & (kAngles - 1);
  *u = {cos_table[th], cos_table[(th - kAngles / 4) & (kAngles - 1)]};
  const double hs = step * kHalfAlong;
  *along_even = static_cast<double>(2 * c.lp) * hs;
  *along_odd = static_cast<double>(2 * c.lp + 1) * hs;
}

bool Skc4Advance(CodecCursor& c, Vec2 target, double step, int64_t* along) {
  const double* cos_table = CosTable();
  Turtle t = FromCursor(c);
  const int32_t th = (t.theta + t.omega) & (kAngles - 1);
  int64_t len = 0, e = 0;
  Vec2 q;
  if (!PlaceNearest(c.p, cos_table, th, target, step, &len, &e, &q)) return false;
  const int64_t a = len - t.lp;
  if (std::abs(a) > kMaxTokenMagnitude) return false;
  const Token at = MakeToken(a), et = MakeToken(e);
  Advance(t, th, len, e, TurnTable(), true);
  t.actx = Mag3(at.symbol);
  t.mag_e = Mag3(et.symbol);
  ToCursor(t, q, &c);
  if (along) *along = a;
  return true;
}

CodecCursor Skc4Restart(Vec2 first, double step) {
  CodecCursor c;
  int64_t x = 0, y = 0;
  if (!StepIndex(first.x, step, &x) || !StepIndex(first.y, step, &y)) return c;
  c.p = {static_cast<double>(x) * step, static_cast<double>(y) * step};
  const Vec2 d = c.p - first;
  c.has_point = d.x * d.x + d.y * d.y <= step * step / 2;
  return c;
}

CodecCursor Skc4Trace(const CodecCursor& start, const Polyline2& line, double step) {
  CodecCursor c;
  if (line.empty()) return c;
  const double bound2 = step * step / 2;
  Vec2 p;
  Turtle t;
  const Vec2 d = line[0] - start.p;
  if (start.has_point && d.x * d.x + d.y * d.y <= bound2) {
    p = start.p;
    t = FromCursor(start);
  } else {
    int64_t x = 0, y = 0;
    if (!StepIndex(line[0].x, step, &x) || !StepIndex(line[0].y, step, &y)) return c;
    p = {static_cast<double>(x) * step, static_cast<double>(y) * step};
  }
  const bool closed = line.size() >= 2 && line.back() == line.front();
  const size_t coded = closed ? line.size() - 1 : line.size();
  if (coded >= 2 && !t.valid) {
    const Vec2 d1 = line[1] - p;
    const double a = std::atan2(d1.y, d1.x) / (2 * std::numbers::pi) * kAngles;
    if (!std::isfinite(a)) return c;
    t = Turtle{};
    t.theta = static_cast<int32_t>(std::llround(a)) & (kAngles - 1);
    t.actx = kAlongStart;
    t.valid = true;
  }
  ToCursor(t, p, &c);
  const Vec2 first = p;
  for (size_t k = 1; k < coded; ++k) {
    if (!Skc4Advance(c, line[k], step, nullptr)) return CodecCursor{};
  }
  if (closed) c.p = first;  // the decoder repeats the first point; the turtle ends at the last
  return c;
}

}  // namespace sculpt::skin::internal
