/// @brief Skin: section construction (naive, offset, hybrid), validation, sampling and the
/// incremental edits (digest §3, §8.4-8.7).
#include "sculpt/skin/skin.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "contour_codec_internal.h"
#include "sampling.h"
#include "sculpt/core/check.h"

namespace sculpt::skin {
namespace {

constexpr int kScanSamples = 128;
constexpr double kPi = std::numbers::pi;

std::string Num(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string BallName(size_t i) { return "balls[" + std::to_string(i) + "]"; }
const char* SideName(int side) { return side > 0 ? "+" : "-"; }

/// min over [0, 1] of 1 + side kappa d: a dense scan refined by golden-section search around the
/// smallest sample, so fixture values hold to several digits (digest §5.2).
double MinOnePlusKd(const Offset& off) {
  int best = 0;
  double vbest = off.OnePlusKappaD(0);
  for (int i = 1; i <= kScanSamples; ++i) {
    const double v = off.OnePlusKappaD(static_cast<double>(i) / kScanSamples);
    if (v < vbest) vbest = v, best = i;
  }
  double lo = std::max(0, best - 1) / static_cast<double>(kScanSamples);
  double hi = std::min(kScanSamples, best + 1) / static_cast<double>(kScanSamples);
  const double g = (std::sqrt(5.0) - 1) / 2;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = off.OnePlusKappaD(x1), f2 = off.OnePlusKappaD(x2);
  for (int it = 0; it < 40; ++it) {
    if (f1 < f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = off.OnePlusKappaD(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = off.OnePlusKappaD(x2);
    }
  }
  return std::min({vbest, f1, f2});
}

SkinPiece OffsetPiece(const Offset& off, double ta, double tb, Vec2 start, Vec2 end) {
  SkinPiece p;
  p.kind = SkinPiece::Kind::kOffset;
  p.tau_a = ta;
  p.tau_b = tb;
  p.start = start;
  p.end = end;
  p.start_tangent = off.D1(ta).Normalized();
  p.end_tangent = off.D1(tb).Normalized();
  return p;
}

SkinPiece SplinePiece(const ASpline& s, double ta, double tb) {
  SkinPiece p;
  p.kind = SkinPiece::Kind::kASpline;
  p.tau_a = ta;
  p.tau_b = tb;
  p.spline = s;
  p.start = s.p0;
  p.end = s.p2;
  p.start_tangent = s.t0;
  p.end_tangent = s.t2;
  return p;
}

/// Builds, samples and validates the section between balls k and k+1.
/// `cursor`: SKC4's decoder at the end of the previous section's sides (no point: none).
Section BuildSectionImpl(const OrientedBall& b0, const OrientedBall& b1, size_t k,
                         const SkinOptions& opt, const std::array<CodecCursor, 2>& cursor,
                         bool restart) {
  Section sec;
  SectionReport& rep = sec.report;
  const HermiteMother mother = HermiteMother::FromBalls(b0, b1);
  const DistanceFn dist{b0.r, b1.r};
  const double L = mother.length;
  const double tol = opt.chord_tolerance;
  const Offset offs[2] = {{&mother, &dist, 1}, {&mother, &dist, -1}};
  const std::string n0 = BallName(k), n1 = BallName(k + 1);

  double min_speed = INFINITY, max_abs_kappa = 0;
  for (int i = 0; i <= kScanSamples; ++i) {
    const double tau = static_cast<double>(i) / kScanSamples;
    min_speed = std::min(min_speed, mother.D1(tau).Length());
    max_abs_kappa = std::max(max_abs_kappa, std::abs(mother.Curvature(tau)));
  }
  rep.mother_regular = min_speed > 1e-6 * L;
  if (!rep.mother_regular) {
    rep.notes.push_back("mother curve singular (min |p'| = " + Num(min_speed / L) +
                        " L): the orientations oppose the chord (digest §6 item 7)");
  }
  for (int s = 0; s < 2; ++s) rep.side[s].min_one_plus_kd = MinOnePlusKd(offs[s]);
  const bool straight = max_abs_kappa * L < 1e-9;
  if (straight && b0.r != b1.r) {
    const double rb = std::max(b0.r, b1.r), rs = std::min(b0.r, b1.r);
    if (L * L < 6 * rb * (rb - rs)) {
      rep.notes.push_back("collinear centres: L^2=" + Num(L * L) + " < 6 r_big (r_big - r_small)=" +
                          Num(6 * rb * (rb - rs)) + ": the offset enters " +
                          (b0.r > b1.r ? n0 : n1) + " near its contact points (digest §3.6)");
    }
  }

  // Pieces per side ([0] = +, [1] = -), in mother-parameter order.
  auto add_offset = [&](int s, double ta, double tb) {
    const int side = s == 0 ? 1 : -1;
    const Vec2 start = ta == 0 ? b0.Contact(side) : offs[s].P(ta);
    const Vec2 end = tb == 1 ? b1.Contact(side) : offs[s].P(tb);
    sec.pieces[s].push_back(OffsetPiece(offs[s], ta, tb, start, end));
  };
  if (opt.method == Method::kOffset) {
    add_offset(0, 0, 1);
    add_offset(1, 0, 1);
  } else if (opt.method == Method::kNaive) {
    for (int s = 0; s < 2; ++s) {
      const int side = s == 0 ? 1 : -1;
      std::string why;
      auto sp = ASpline::Make(b0.Contact(side), b0.t(), 1 / b0.r, b1.Contact(side), b1.t(),
                              1 / b1.r, opt.delta, &why);
      if (sp) {
        sec.pieces[s].push_back(SplinePiece(*sp, 0, 1));
      } else {
        rep.notes.push_back(std::string("naive: side ") + SideName(side) +
                            " has no A-spline (" + why + "); offset used");
        add_offset(s, 0, 1);
      }
    }
  } else if (straight) {
    // kappa == 0: no exterior side, parallel tangents, no control triangle (digest §3.6).
    rep.notes.push_back("hybrid: straight mother, offset on both sides");
    add_offset(0, 0, 1);
    add_offset(1, 0, 1);
  } else {
    std::array<double, 2> roots{};
    const int nroots = mother.Inflections(roots);
    std::vector<double> cuts{0.0};
    for (int i = 0; i < nroots; ++i) {
      cuts.push_back(roots[i]);
      // Hidden ball at the inflection (digest §3.5 step 4): on the original cubic and d(s).
      const Vec2 tan = mother.D1(roots[i]);
      rep.hidden.push_back({mother.P(roots[i]), dist.D(roots[i]), std::atan2(tan.y, tan.x)});
    }
    cuts.push_back(1.0);
    for (size_t j = 0; j + 1 < cuts.size(); ++j) {
      const double ta = cuts[j], tb = cuts[j + 1];
      const double sigma = mother.Curvature(0.5 * (ta + tb)) >= 0 ? 1.0 : -1.0;
      const int ext = sigma > 0 ? 0 : 1;  // side * sigma > 0: exterior (digest §3.5 step 2)
      const int in = 1 - ext;
      const int in_side = in == 0 ? 1 : -1;
      add_offset(ext, ta, tb);
      // Interior: A-spline with the offset's tangents at hidden balls and t_i at real ones, and
      // the mother's curvature as node curvature (digest §3.5 steps 3 and 5).
      const Vec2 pa = ta == 0 ? b0.Contact(in_side) : offs[in].P(ta);
      const Vec2 pb = tb == 1 ? b1.Contact(in_side) : offs[in].P(tb);
      const Vec2 tga = ta == 0 ? b0.t() : offs[in].D1(ta).Normalized();
      const Vec2 tgb = tb == 1 ? b1.t() : offs[in].D1(tb).Normalized();
      std::string why;
      auto sp = ASpline::Make(pa, tga, std::abs(mother.Curvature(ta)), pb, tgb,
                              std::abs(mother.Curvature(tb)), opt.delta, &why);
      if (sp && sp->TurnSign() != sigma) {
        why = "the A-spline would turn against the mother (digest Fig. 2.19)";
        sp.reset();
      }
      if (sp) {
        sec.pieces[in].push_back(SplinePiece(*sp, ta, tb));
      } else {
        rep.notes.push_back(std::string("hybrid: side ") + SideName(in_side) + " on tau [" +
                            Num(ta) + ", " + Num(tb) + "] has no A-spline (" + why +
                            "); offset used (digest §8.4 step 5)");
        add_offset(in, ta, tb);
      }
    }
  }

  // Sampling: each side as one curve over its pieces (piece j on u in [j, j+1]), pinned to the
  // contact points at both ends so neighbouring sections share them exactly.
  for (int s = 0; s < 2; ++s) {
    Polyline2& out = s == 0 ? sec.plus : sec.minus;
    const auto& pieces = sec.pieces[s];
    const Offset& off = offs[s];
    const int np = static_cast<int>(pieces.size());
    const auto side_curve = [&](double u) {
      const int j = std::clamp(static_cast<int>(std::floor(u)), 0, np - 1);
      const double w = u - j;
      const SkinPiece& p = pieces[j];
      if (p.kind == SkinPiece::Kind::kOffset) return off.P(p.tau_a + (p.tau_b - p.tau_a) * w);
      return p.spline.AtPhi(kPi / 2 * (1 - w));
    };
    const CodecCursor start =
        restart ? internal::Skc4Restart(pieces.front().start, tol) : cursor[s];
    if (opt.sample_for_codec) {
      internal::SampleSideForCodec(side_curve, np, tol, start, out);
    } else {
      internal::SampleSide(side_curve, np, tol, out);
    }
    out.front() = pieces.front().start;
    out.back() = pieces.back().end;
    if (opt.sample_for_codec) sec.codec_end[s] = internal::Skc4Trace(start, out, tol);
    for (const SkinPiece& p : pieces) {
      if (p.kind == SkinPiece::Kind::kOffset) {
        ++rep.side[s].offset_pieces;
      } else {
        ++rep.side[s].aspline_pieces;
      }
    }
  }

  // An offset whose 1 + kappa d is negative at a ball runs against t_i there: the contour is not
  // G1 at that contact point and cannot be repaired by node insertion (digest §3.6, §6 item 8).
  for (int s = 0; s < 2; ++s) {
    for (const SkinPiece& p : sec.pieces[s]) {
      if (p.kind != SkinPiece::Kind::kOffset) continue;
      for (double tau : {p.tau_a, p.tau_b}) {
        if ((tau == 0 || tau == 1) && offs[s].OnePlusKappaD(tau) <= 0) {
          rep.end_reversed = true;
          rep.notes.push_back(std::string("side ") + SideName(s == 0 ? 1 : -1) +
                              " offset runs backwards at " + (tau == 0 ? n0 : n1) +
                              " (1+kappa d=" + Num(offs[s].OnePlusKappaD(tau)) +
                              "): not G1 there (digest §3.6)");
        }
      }
    }
  }

  // Validation on the sampled contour (digest §7 claims 21-22, §8.7).
  const OrientedBall* balls[2] = {&b0, &b1};
  const std::string names[2] = {n0, n1};
  const double eps = 1e-9 * (L + b0.r + b1.r);
  for (int s = 0; s < 2; ++s) {
    const Polyline2& pl = s == 0 ? sec.plus : sec.minus;
    SideReport& sr = rep.side[s];
    sr.self_intersections = internal::CountCrossings(pl, false);
    double clear = INFINITY;
    int worst = 0;
    for (const Vec2& p : pl) {
      for (int j = 0; j < 2; ++j) {
        const double c = (p - balls[j]->c).Length() - balls[j]->r;
        if (c < clear) clear = c, worst = j;
      }
    }
    sr.clearance = clear;
    if (sr.self_intersections > 0) {
      rep.notes.push_back(std::string("side ") + SideName(s == 0 ? 1 : -1) + " crosses itself (" +
                          std::to_string(sr.self_intersections) + " crossings; min(1+kappa d)=" +
                          Num(sr.min_one_plus_kd) + ")");
    }
    if (clear < -(tol + eps)) {
      rep.notes.push_back(std::string("side ") + SideName(s == 0 ? 1 : -1) + " enters " +
                          names[worst] + " by " + Num(-clear) + " (chord tolerance " + Num(tol) +
                          ")");
    }
  }
  rep.clearance = std::min(rep.side[0].clearance, rep.side[1].clearance);
  return sec;
}

/// The closed contour of a section (digest Def 2.3), counter-clockwise.
Polyline2 ClosedContour(const Section& sec, const OrientedBall& b0, const OrientedBall& b1,
                        double tol) {
  Polyline2 loop(sec.plus);
  const Polyline2 front = SampleCap(b1, 1, tol);
  loop.insert(loop.end(), front.begin() + 1, front.end());
  loop.insert(loop.end(), sec.minus.rbegin() + 1, sec.minus.rend());
  const Polyline2 rear = SampleCap(b0, -1, tol);
  loop.insert(loop.end(), rear.begin() + 1, rear.end() - 1);
  return loop;
}

void FinishValidation(Section& sec, const OrientedBall& b0, const OrientedBall& b1, size_t k,
                      double tol) {
  SectionReport& rep = sec.report;
  const Polyline2 loop = ClosedContour(sec, b0, b1, tol);
  const int crossings = internal::CountCrossings(loop, true);
  rep.simple = crossings == 0 && rep.mother_regular && !rep.end_reversed;
  if (crossings > 0) {
    rep.notes.push_back("closed contour not simple (" + std::to_string(crossings) +
                        " crossings, digest Def 2.4)");
  }
  const double eps = 1e-9 * ((b1.c - b0.c).Length() + b0.r + b1.r);
  bool inside = true;
  const OrientedBall* balls[2] = {&b0, &b1};
  for (int j = 0; j < 2; ++j) {
    const int w = internal::Winding(loop, balls[j]->c);
    const double dmin = internal::DistanceToClosed(loop, balls[j]->c);
    if (w != 1 || dmin < balls[j]->r - tol - eps) {
      inside = false;
      rep.notes.push_back(BallName(k + j) + " not inside the closed contour (winding " +
                          std::to_string(w) + ", centre-to-contour " + Num(dmin) + " vs radius " +
                          Num(balls[j]->r) + ", digest Def 2.5)");
    }
  }
  rep.total = rep.simple && inside;
}

}  // namespace

const char* MethodName(Method m) {
  switch (m) {
    case Method::kNaive:
      return "naive";
    case Method::kOffset:
      return "offset";
    case Method::kHybrid:
      return "hybrid";
  }
  return "hybrid";
}

StatusOr<Method> ParseMethod(const std::string& name) {
  if (name == "naive") return Method::kNaive;
  if (name == "offset") return Method::kOffset;
  if (name == "hybrid") return Method::kHybrid;
  return Outside("method", name, "{naive, offset, hybrid}");
}

Polyline2 SampleCap(const OrientedBall& ball, int from_side, double tol) {
  const Vec2 start = ball.Contact(from_side), end = ball.Contact(-from_side);
  const Vec2 rel = start - ball.c;
  const double a0 = std::atan2(rel.y, rel.x);
  // Chord sagitta r (1 - cos(h/2)) <= tol for angular step h.
  const double c = std::clamp(1 - tol / ball.r, -1.0, 1.0);
  const double h = std::max(2 * std::acos(c), 1e-9);
  const int n = std::clamp(static_cast<int>(std::ceil(kPi / h)), 4, 1 << 22);
  Polyline2 pts;
  pts.reserve(n + 1);
  pts.push_back(start);
  for (int i = 1; i < n; ++i) {
    const double a = a0 + kPi * i / n;
    pts.push_back(ball.c + Vec2{std::cos(a), std::sin(a)} * ball.r);
  }
  pts.push_back(end);
  return pts;
}

Section BuildSection(const OrientedBall& b0, const OrientedBall& b1, const SkinOptions& options) {
  Section s = BuildSectionImpl(b0, b1, 0, options, {}, options.sample_for_codec);
  s.codec_restart = options.sample_for_codec;
  FinishValidation(s, b0, b1, 0, options.chord_tolerance);
  return s;
}

StatusOr<Skin> Skin::Build(std::vector<OrientedBall> balls, const SkinOptions& options) {
  SCULPT_RETURN_IF_ERROR(ValidateChain(balls));
  SkinOptions opt = options;
  double min_r = INFINITY, extent = 0;
  for (const OrientedBall& b : balls) {
    min_r = std::min(min_r, b.r);
    extent = std::max({extent, std::abs(b.c.x) + b.r, std::abs(b.c.y) + b.r});
  }
  SCULPT_RETURN_IF_ERROR(CheckRange("delta", opt.delta, -1e300, 1e3));
  SCULPT_RETURN_IF_ERROR(CheckRange("chord_tolerance", opt.chord_tolerance, -1e300, 1e300));
  if (opt.chord_tolerance <= 0) opt.chord_tolerance = 1e-3 * min_r;
  // Below 1e-12 of the coordinates' magnitude the chord test compares rounding noise.
  const double lo = 1e-12 * extent;
  if (opt.chord_tolerance < lo) {
    return Outside("chord_tolerance", FormatNumber(opt.chord_tolerance),
                   std::string("[") + FormatNumber(lo) + ", inf) for coordinates up to " +
                       FormatNumber(extent));
  }
  Skin skin;
  skin.balls_ = std::move(balls);
  skin.options_ = opt;
  skin.sections_.reserve(skin.balls_.size() - 1);
  for (size_t k = 0; k + 1 < skin.balls_.size(); ++k) skin.sections_.push_back(skin.MakeSection(k));
  return skin;
}

bool Skin::CodecRestart(size_t k) const {
  if (k == 0) return true;
  // SplitMix64's finaliser over the ball's bits: the same on every machine.
  const OrientedBall& b = balls_[k];
  uint64_t h = 0;
  for (double v : {b.c.x, b.c.y, b.r, b.theta}) {
    h = (h ^ std::bit_cast<uint64_t>(v)) + 0x9e3779b97f4a7c15ull;
    h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
    h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
    h ^= h >> 31;
  }
  return h % kCodecRestartPeriod == 0;
}

Section Skin::MakeSection(size_t k) {
  // The side's previous section, as the snapshot's decoder will have it, unless the section
  // restarts the codec.
  const std::array<CodecCursor, 2> none{};
  const bool restart = options_.sample_for_codec && CodecRestart(k);
  Section s = BuildSectionImpl(balls_[k], balls_[k + 1], k, options_,
                               k > 0 && k - 1 < sections_.size() ? sections_[k - 1].codec_end
                                                                  : none,
                               restart);
  s.codec_restart = restart;
  FinishValidation(s, balls_[k], balls_[k + 1], k, options_.chord_tolerance);
  s.id = next_id_++;
  s.version = 1;
  return s;
}

void Skin::Rebuild(size_t k, SkinChange& change) {
  Section s = MakeSection(k);
  s.id = sections_[k].id;
  s.version = sections_[k].version + 1;
  --next_id_;
  sections_[k] = std::move(s);
  change.changed.push_back(k);
}

void Skin::FollowToRestart(SkinChange& change) {
  if (!options_.sample_for_codec || change.changed.empty()) return;
  for (size_t k = change.changed.back() + 1; k < sections_.size() && !CodecRestart(k); ++k) {
    Rebuild(k, change);
  }
}

StatusOr<SkinChange> Skin::SetBall(size_t i, const OrientedBall& ball) {
  const size_t n = balls_.size();
  if (i >= n) {
    return Outside("ball index", std::to_string(i),
                   std::string("[0, ") + std::to_string(n - 1) + "]");
  }
  SCULPT_RETURN_IF_ERROR(ValidateBall(BallName(i), ball));
  if (i > 0) SCULPT_RETURN_IF_ERROR(CheckAdmissiblePair(i - 1, balls_[i - 1], ball));
  if (i + 1 < n) SCULPT_RETURN_IF_ERROR(CheckAdmissiblePair(i, ball, balls_[i + 1]));
  balls_[i] = ball;
  SkinChange change;
  for (size_t k : {i - 1, i}) {
    if (k >= n - 1) continue;  // i - 1 wraps for i == 0; i is past the end for the last ball
    Rebuild(k, change);
  }
  FollowToRestart(change);
  return change;
}

StatusOr<SkinChange> Skin::InsertBall(size_t i, const OrientedBall& ball) {
  const size_t n = balls_.size();
  if (i > n) {
    return Outside("ball index", std::to_string(i), std::string("[0, ") + std::to_string(n) + "]");
  }
  SCULPT_RETURN_IF_ERROR(ValidateBall(BallName(i), ball));
  if (i > 0) SCULPT_RETURN_IF_ERROR(CheckAdmissiblePair(i - 1, balls_[i - 1], ball));
  if (i < n) SCULPT_RETURN_IF_ERROR(CheckAdmissiblePair(i, ball, balls_[i]));
  balls_.insert(balls_.begin() + static_cast<std::ptrdiff_t>(i), ball);
  SkinChange change;
  if (i == 0) {
    change = {{0}, 0, 0, 1};
  } else if (i == n) {
    change = {{n - 1}, n - 1, 0, 1};
  } else {
    change = {{i - 1, i}, i - 1, 1, 2};
  }
  // Spliced one section at a time, so that the second new section's sampler starts from the
  // first (MakeSection reads the section before it), not from the section it replaces.
  const auto at = sections_.begin() + static_cast<std::ptrdiff_t>(change.splice_at);
  sections_.erase(at, at + static_cast<std::ptrdiff_t>(change.removed));
  for (size_t k : change.changed) {
    Section s = MakeSection(k);
    sections_.insert(sections_.begin() + static_cast<std::ptrdiff_t>(k), std::move(s));
  }
  FollowToRestart(change);
  return change;
}

StatusOr<SkinChange> Skin::RemoveBall(size_t i) {
  const size_t n = balls_.size();
  if (i >= n) {
    return Outside("ball index", std::to_string(i),
                   std::string("[0, ") + std::to_string(n - 1) + "]");
  }
  if (n <= 2) {
    return FailedPrecondition("balls.size=" + std::to_string(n) +
                              ": a skin keeps at least two balls");
  }
  if (i > 0 && i + 1 < n) {
    SCULPT_RETURN_IF_ERROR(CheckAdmissiblePair(i - 1, balls_[i - 1], balls_[i + 1]));
  }
  balls_.erase(balls_.begin() + static_cast<std::ptrdiff_t>(i));
  SkinChange change;
  if (i == 0) {
    change = {{}, 0, 1, 0};
  } else if (i == n - 1) {
    change = {{}, n - 2, 1, 0};
  } else {
    change = {{i - 1}, i - 1, 2, 1};
  }
  std::vector<Section> fresh;
  for (size_t k : change.changed) fresh.push_back(MakeSection(k));
  const auto at = sections_.begin() + static_cast<std::ptrdiff_t>(change.splice_at);
  sections_.erase(at, at + static_cast<std::ptrdiff_t>(change.removed));
  sections_.insert(sections_.begin() + static_cast<std::ptrdiff_t>(change.splice_at),
                   fresh.begin(), fresh.end());
  // The first ball went: the new first section restarts (k = 0). No section follows a new last.
  if (i == 0 && options_.sample_for_codec) Rebuild(0, change);
  FollowToRestart(change);
  return change;
}

Polyline2 Skin::SectionOutline(size_t k) const {
  return ClosedContour(sections_[k], balls_[k], balls_[k + 1], options_.chord_tolerance);
}

Polyline2 Skin::Chain(int side) const {
  Polyline2 out;
  for (const Section& s : sections_) {
    const Polyline2& p = side > 0 ? s.plus : s.minus;
    out.insert(out.end(), p.begin() + (out.empty() ? 0 : 1), p.end());
  }
  return out;
}

Polyline2 Skin::Outline() const {
  Polyline2 loop = Chain(1);
  const Polyline2 minus = Chain(-1);
  const Polyline2 front = SampleCap(balls_.back(), 1, options_.chord_tolerance);
  loop.insert(loop.end(), front.begin() + 1, front.end());
  loop.insert(loop.end(), minus.rbegin() + 1, minus.rend());
  const Polyline2 rear = SampleCap(balls_.front(), -1, options_.chord_tolerance);
  loop.insert(loop.end(), rear.begin() + 1, rear.end() - 1);
  return loop;
}

SkinSummary Skin::Summary() const {
  SkinSummary s;
  s.sections = sections_.size();
  s.min_clearance = INFINITY;
  for (const Section& sec : sections_) {
    s.total += sec.report.total;
    s.simple += sec.report.simple;
    s.points += sec.plus.size() + sec.minus.size();
    s.min_clearance = std::min(s.min_clearance, sec.report.clearance);
  }
  return s;
}

}  // namespace sculpt::skin
