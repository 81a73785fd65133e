/// @brief Writes contour codec fixtures for the web client's JS decoder test
/// (client/web/test/contour_codec_test.mjs): messages from the C++ encoder with what the C++
/// decoder makes of them, and truncated / corrupted variants with the C++ verdict.
///
/// Usage: contour_fixtures OUT.json. Seeded: the same build writes the same file.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "contour_codec_internal.h"
#include "sculpt/skin/contour_codec.h"
#include "sculpt/skin/skin.h"

namespace sculpt::skin {
namespace {

using nlohmann::json;

std::string Hex(const std::string& bytes) {
  static const char* kDigits = "0123456789abcdef";
  std::string out;
  for (unsigned char c : bytes) {
    out.push_back(kDigits[c >> 4]);
    out.push_back(kDigits[c & 15]);
  }
  return out;
}

/// The encoder's bytes; the fixtures are valid input, so an error is a bug here: exit.
std::string Must(StatusOr<std::string> bytes) {
  if (!bytes.ok()) {
    std::fprintf(stderr, "contour_fixtures: %s\n", std::string(bytes.status().message()).c_str());
    std::exit(1);
  }
  return *std::move(bytes);
}

/// Interleaved x, y (non-finite values become null, as nlohmann writes them).
json Points(const Polyline2& line) {
  json out = json::array();
  for (const Vec2& p : line) {
    out.push_back(p.x);
    out.push_back(p.y);
  }
  return out;
}

json Lines(const std::vector<Polyline2>& lines) {
  json out = json::array();
  for (const Polyline2& l : lines) out.push_back(Points(l));
  return out;
}

json ViewState(const ContourView& view) {
  json sections = json::array();
  for (const SectionContour& s : view.sections()) {
    sections.push_back({{"id", s.id},
                        {"version", s.version},
                        {"plus", Points(s.plus)},
                        {"minus", Points(s.minus)}});
  }
  return {{"step", view.step()},
          {"sections", sections},
          {"chain_plus", Points(view.Chain(1))},
          {"chain_minus", Points(view.Chain(-1))}};
}

/// Polyline shapes, chosen so the encoder picks each coding: short lines cost less as varints,
/// long smooth ones go to Draco's raw scheme, wide random jumps to its tagged scheme.
struct Shapes {
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> unit{-1, 1};

  Polyline2 Arc(int n, double radius, double cx, double cy, double dtheta) {
    Polyline2 l;
    for (int i = 0; i < n; ++i) {
      l.push_back({cx + radius * std::cos(i * dtheta), cy + radius * std::sin(i * dtheta)});
    }
    return l;
  }
  /// Uniform points in a square of half-width `w`: residuals of any size up to ~4 w / step.
  Polyline2 Noise(int n, double w) {
    Polyline2 l;
    for (int i = 0; i < n; ++i) l.push_back({w * unit(rng), w * unit(rng)});
    return l;
  }
  /// A random walk: many distinct mid-sized residuals (a wide raw alphabet).
  Polyline2 Walk(int n, double stride) {
    Polyline2 l{{0, 0}};
    for (int i = 1; i < n; ++i) {
      l.push_back({l.back().x + stride * unit(rng), l.back().y + stride * unit(rng)});
    }
    return l;
  }
  /// A straight line at constant speed (residuals 0) with a random bump every `every` points:
  /// mostly zeros and hundreds of distinct rare values, which Draco codes with its raw scheme
  /// at more than the minimum 12 bits of rANS precision.
  Polyline2 BumpyLine(int n, double speed, int every, double bump) {
    Polyline2 l;
    for (int i = 0; i < n; ++i) {
      l.push_back({speed * i, i % every == 0 ? bump * unit(rng) : 0});
    }
    return l;
  }
  Polyline2 Random(int kind) {
    std::uniform_int_distribution<int> len(2, 40);
    switch (kind) {
      case 0:
        return {};
      case 1:
        return {{100 * unit(rng), 100 * unit(rng)}};
      case 2:
        return Noise(len(rng) % 4 + 2, 3);
      case 3:
        return Arc(len(rng) * 20, 1 + 5 * std::abs(unit(rng)), unit(rng), unit(rng), 0.01);
      case 4:
        return Noise(len(rng), 2000);
      default:
        return Walk(len(rng) * 30, 0.05);
    }
  }
};

struct SetCase {
  std::string name;
  std::vector<Polyline2> lines;
  double step;
};

std::vector<SetCase> PolylineSets() {
  Shapes s{std::mt19937_64(20261123)};
  std::vector<SetCase> cases;
  cases.push_back({"no_polylines", {}, 1e-3});
  cases.push_back({"empty_polylines", {{}, {}, {}}, 0.5});
  cases.push_back(
      {"single_points", {{{0, 0}}, {{-3.25, 7.5}}, {{1e6, -1e6}}, {}, {{0.001, 0}}}, 1e-3});
  cases.push_back({"two_and_three_points", {{{0, 0}, {1, 1}}, {{1, 1}, {2, 3}, {4, 4}}}, 1e-2});
  cases.push_back({"long_circle", {s.Arc(2000, 7, 0, 0, 0.005)}, 1e-4});
  cases.push_back({"small_circle", {s.Arc(120, 2, 1, 1, 0.05)}, 1e-3});
  {
    Polyline2 loop = s.Arc(127, 3, 0, 0, 2 * std::numbers::pi / 126);
    loop.back() = loop.front();
    cases.push_back({"closed_loops", {loop, {{1, 1}, {1, 1}}, {{0, 0}, {3, 0}, {0, 0}}}, 1e-3});
  }
  cases.push_back({"wide_noise", {s.Noise(400, 1000)}, 1e-3});
  cases.push_back({"small_noise", {s.Noise(40, 1000)}, 1e-3});
  cases.push_back({"random_walk", {s.Walk(3000, 1)}, 1e-3});
  cases.push_back({"bumpy_line", {s.BumpyLine(12000, 0.01, 25, 0.3)}, 1e-3});
  cases.push_back({"mixed", {{}, s.Arc(500, 3, 0, 0, 0.01), {{5, 5}}, s.Noise(30, 2), {}}, 1e-3});
  // Near the 2^52-step limit: residuals beyond 2^53 (exact only as 64-bit integers).
  cases.push_back({"huge_residuals",
                   {{{4.5e15, -4.5e15}, {-4.5e15, 4.5e15}, {4.5e15, 4.5e15}, {-4.5e15, 0}}},
                   1});
  cases.push_back({"coarse_step", {s.Arc(300, 50, 0, 0, 0.02), s.Walk(200, 3)}, 0.37});
  cases.push_back({"fine_step", {s.Arc(300, 0.01, 0, 0, 0.02)}, 1e-9});
  std::uniform_int_distribution<int> nlines(0, 6), kind(0, 5);
  const double steps[] = {1e-6, 1e-3, 0.37, 2.0};
  for (int k = 0; k < 24; ++k) {
    SetCase c{"random_" + std::to_string(k), {}, steps[k % 4]};
    for (int n = nlines(s.rng); n > 0; --n) c.lines.push_back(s.Random(kind(s.rng)));
    cases.push_back(std::move(c));
  }
  return cases;
}

constexpr double kDeg = std::numbers::pi / 180;

std::vector<OrientedBall> Wavy(int n) {
  std::vector<OrientedBall> balls;
  for (int i = 0; i < n; ++i) {
    balls.push_back({{2.5 * i, 0.8 * std::sin(0.7 * i)},
                     0.6 + 0.3 * std::cos(1.3 * i),
                     20 * kDeg * std::cos(0.7 * i)});
  }
  return balls;
}

/// The benchmark's chain (tests/bench/skin_bench.cc Chain): radii 0.5-1, gaps 1.1-2 times the
/// radii, headings within 35 deg, touching directions within 20 deg of the heading.
std::vector<OrientedBall> BenchChain(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<OrientedBall> b;
  Vec2 c{0, 0};
  double heading = 0;
  while (b.size() < n) {
    const double r = 0.5 + 0.5 * u(rng);
    Vec2 nc = c;
    double h = heading;
    if (!b.empty()) {
      h = std::clamp(heading + (u(rng) - 0.5) * 40 * kDeg, -35 * kDeg, 35 * kDeg);
      nc = c + Vec2{std::cos(h), std::sin(h)} * ((b.back().r + r) * (1.1 + 0.9 * u(rng)));
    }
    const OrientedBall ball{nc, r, h + (u(rng) - 0.5) * 40 * kDeg};
    if (!b.empty() && !CheckAdmissiblePair(b.size() - 1, b.back(), ball).ok()) continue;
    b.push_back(ball);
    c = nc;
    heading = h;
  }
  return b;
}

/// Applies `bytes` to `view` and records the verdict and the view after it.
json Step(ContourView& view, const std::string& what, const std::string& bytes) {
  const Status s = view.Apply(bytes);
  json out = ViewState(view);
  out["what"] = what;
  out["bytes"] = Hex(bytes);
  out["ok"] = s.ok();
  if (!s.ok()) out["error"] = std::string(s.message());
  return out;
}

/// A skin edited by SetBall, InsertBall and RemoveBall, its snapshot and every update applied
/// in order to a ContourView, plus updates that must be refused.
json SkinSequence(const std::string& name, int balls, double step, uint64_t seed, int edits) {
  auto skin = Skin::Build(Wavy(balls));
  if (!skin.ok()) throw std::runtime_error(std::string(skin.status().message()));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1, 1);
  ContourView view;
  json steps = json::array();
  steps.push_back(Step(view, "snapshot", Must(EncodeSkinSnapshot(*skin, step))));
  std::string last_insert;
  for (int e = 0; e < edits; ++e) {
    const size_t n = skin->balls().size();
    StatusOr<SkinChange> change = InvalidArgument("none");
    std::string what;
    switch (e % 5) {
      case 3: {  // insert between two balls, midway
        const size_t i = 1 + rng() % (n - 1);
        const OrientedBall& a = skin->balls()[i - 1];
        const OrientedBall& b = skin->balls()[i];
        change = skin->InsertBall(i, {{(a.c.x + b.c.x) / 2, (a.c.y + b.c.y) / 2 + 0.1},
                                      std::min(a.r, b.r) * 0.9,
                                      (a.theta + b.theta) / 2});
        what = "insert " + std::to_string(i);
        break;
      }
      case 4:
        if (n > 3) {
          const size_t i = rng() % n;
          change = skin->RemoveBall(i);
          what = "remove " + std::to_string(i);
          break;
        }
        [[fallthrough]];
      default: {
        const size_t i = rng() % n;
        OrientedBall b = skin->balls()[i];
        b.c.y += 0.15 * unit(rng);
        b.r *= 1 + 0.1 * unit(rng);
        b.theta += 5 * kDeg * unit(rng);
        change = skin->SetBall(i, b);
        what = "set " + std::to_string(i);
      }
    }
    if (!change.ok()) continue;  // an inadmissible edit: the skin is unchanged
    const std::string bytes = Must(EncodeSkinUpdate(*skin, *change, step));
    steps.push_back(Step(view, what, bytes));
    if (what.starts_with("insert")) last_insert = bytes;
  }
  // Refusals that leave the view unchanged: an insert applied twice no longer fits, a polyline
  // set is not a skin message.
  if (!last_insert.empty()) steps.push_back(Step(view, "insert again", last_insert));
  const double set_step = step > 0 ? step : skin->chord_tolerance();
  steps.push_back(Step(view, "polyline set", Must(EncodeContours({{{0, 0}, {1, 1}}}, set_step))));
  steps.push_back(Step(view, "snapshot again", Must(EncodeSkinSnapshot(*skin, step))));
  return {{"name", name}, {"steps", steps}};
}

/// Every prefix, some single-byte corruptions and an extra byte of `bytes`, each with the C++
/// verdict: DecodeContours for a polyline set, Apply to a copy of `base` for a skin message.
/// `base_bytes` (applied to an empty view) make `base`, so that JS can rebuild it.
json Corruptions(const std::string& name, const std::string& bytes, const ContourView* base,
                 const std::string& base_bytes, uint64_t seed, int flips) {
  std::vector<std::string> variants;
  for (size_t n = 0; n < bytes.size(); ++n) variants.push_back(bytes.substr(0, n));
  std::mt19937_64 rng(seed);
  for (int k = 0; k < flips; ++k) {
    std::string b = bytes;
    b[rng() % b.size()] ^= static_cast<char>(1 + rng() % 255);
    variants.push_back(b);
  }
  variants.push_back(bytes + '\0');
  json out = json::array();
  for (const std::string& v : variants) {
    json r = {{"bytes", Hex(v)}};
    if (base) {
      ContourView view = *base;
      const Status s = view.Apply(v);
      r["ok"] = s.ok();
      if (s.ok()) r["view"] = ViewState(view);
    } else {
      const auto lines = DecodeContours(v);
      r["ok"] = lines.ok();
      if (lines.ok()) r["lines"] = Lines(*lines);
    }
    out.push_back(r);
  }
  json c = {{"name", name}, {"bytes", Hex(bytes)}, {"variants", out}};
  if (base) {
    c["base"] = ViewState(*base);
    c["base_bytes"] = Hex(base_bytes);
  }
  return c;
}

int Main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.json\n", argv[0]);
    return 2;
  }
  json sets = json::array();
  for (const SetCase& c : PolylineSets()) {
    const auto bytes = EncodeContours(c.lines, c.step);
    if (!bytes.ok()) {
      std::fprintf(stderr, "%s: %s\n", c.name.c_str(),
                   std::string(bytes.status().message()).c_str());
      return 1;
    }
    const auto back = DecodeContours(*bytes);
    if (!back.ok()) return 1;
    sets.push_back(
        {{"name", c.name}, {"bytes", Hex(*bytes)}, {"step", c.step}, {"lines", Lines(*back)}});
    // The same lines in each format alone (the default keeps the smaller of SKC3 and SKC2).
    const std::pair<const char*, StatusOr<std::string> (*)(const std::vector<Polyline2>&, double)>
        forced[] = {{"_skc4", internal::EncodeContoursSkc4},
                    {"_skc3", internal::EncodeContoursSkc3},
                    {"_skc2", internal::EncodeContoursSkc2},
                    {"_skc1", internal::EncodeContoursSkc1}};
    for (const auto& [suffix, encode] : forced) {
      const std::string old = Must(encode(c.lines, c.step));
      const auto old_back = DecodeContours(old);
      if (!old_back.ok()) return 1;
      sets.push_back({{"name", c.name + suffix},
                      {"bytes", Hex(old)},
                      {"step", c.step},
                      {"lines", Lines(*old_back)}});
    }
  }
  json views = json::array();
  views.push_back(SkinSequence("wavy12_chord_step", 12, 0, 7, 30));
  views.push_back(SkinSequence("wavy6_fine_step", 6, 1e-5, 11, 12));

  // Corruptions of small messages of each coding, and of a skin snapshot and update.
  Shapes s{std::mt19937_64(5)};
  json corrupt = json::array();
  auto skc1 = [](const std::vector<Polyline2>& lines, double step) {
    return Must(internal::EncodeContoursSkc1(lines, step));
  };
  corrupt.push_back(
      Corruptions("varint", skc1({s.Noise(4, 3), {{1, 2}}, {}}, 1e-3), nullptr, "", 1, 400));
  corrupt.push_back(
      Corruptions("raw", skc1({s.Arc(120, 2, 1, 1, 0.05)}, 1e-3), nullptr, "", 2, 400));
  corrupt.push_back(
      Corruptions("arc", skc1({s.Arc(60, 2, 0, 0, 0.05)}, 1e-3), nullptr, "", 6, 200));
  corrupt.push_back(Corruptions("tagged", skc1({s.Noise(40, 1000)}, 1e-3), nullptr, "", 3, 400));
  corrupt.push_back(Corruptions("curve", Must(EncodeContours({s.Arc(60, 2, 0, 0, 0.05)}, 1e-3)),
                                nullptr, "", 7, 400));
  corrupt.push_back(Corruptions(
      "curve_mixed", Must(EncodeContours({s.Noise(5, 3), {}, s.Walk(40, 0.1), {{2, 2}}}, 1e-3)),
      nullptr, "", 8, 400));
  auto skc3 = [](const std::vector<Polyline2>& lines, double step) {
    return Must(internal::EncodeContoursSkc3(lines, step));
  };
  corrupt.push_back(
      Corruptions("turtle", skc3({s.Arc(60, 2, 0, 0, 0.05)}, 1e-3), nullptr, "", 9, 400));
  corrupt.push_back(Corruptions(
      "turtle_mixed", skc3({s.Noise(5, 3), {}, s.Walk(40, 0.1), {{2, 2}}, s.Noise(30, 1e3)}, 1e-3),
      nullptr, "", 10, 400));
  auto skin = Skin::Build(Wavy(4));
  if (!skin.ok()) return 1;
  ContourView empty;
  corrupt.push_back(Corruptions("snapshot_skc3", Must(internal::EncodeSkinSnapshotSkc3(*skin)),
                                &empty, "", 11, 200));
  // SKC4 (the chord rule) on a skin sampled for it.
  SkinOptions follow;
  follow.sample_for_codec = true;
  auto wavy12 = Skin::Build(Wavy(12), follow);
  if (!wavy12.ok()) return 1;
  corrupt.push_back(Corruptions("snapshot_skc4", Must(internal::EncodeSkinSnapshotSkc4(*wavy12)),
                                &empty, "", 12, 200));
  const std::string snap = Must(EncodeSkinSnapshot(*skin));
  corrupt.push_back(Corruptions("snapshot", snap, &empty, "", 4, 120));
  ContourView view;
  if (!view.Apply(snap).ok()) return 1;
  OrientedBall b = skin->balls()[1];
  b.c.y += 0.1;
  const auto change = skin->SetBall(1, b);
  if (!change.ok()) return 1;
  corrupt.push_back(
      Corruptions("update", Must(EncodeSkinUpdate(*skin, *change)), &view, snap, 5, 120));

  // The benchmark's skin (tests/bench/skin_bench.cc: 1,000 balls, seed 20261122 + 1000) as one
  // snapshot, for the JS decoder's speed on the same data as `sculpt-bench skin`.
  auto big = Skin::Build(BenchChain(1000, 20261122 + 1000));
  if (!big.ok()) return 1;
  size_t big_points = 0;
  for (const Section& sec : big->sections()) big_points += sec.plus.size() + sec.minus.size();
  const json bench = {{"bytes", Hex(Must(EncodeSkinSnapshot(*big)))},
                      {"skc2_bytes", Hex(Must(internal::EncodeSkinSnapshotSkc2(*big)))},
                      {"skc1_bytes", Hex(Must(internal::EncodeSkinSnapshotSkc1(*big)))},
                      {"points", big_points}};

  std::ofstream out(argv[1]);
  out << json{{"sets", sets}, {"views", views}, {"corrupt", corrupt}, {"bench", bench}}.dump();
  return out.good() ? 0 : 1;
}

}  // namespace
}  // namespace sculpt::skin

int main(int argc, char** argv) { return sculpt::skin::Main(argc, argv); }
