/// @brief `sculpt-bench skin`: ball-skin build time against chain length, update time after one
/// move, contour bytes against float32 and Draco, codec speed, and what accuracy costs.
#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/point_cloud/point_cloud_builder.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

#include "bench_common.h"
#include "skin/contour_codec_internal.h"
#include "sculpt/skin/contour_codec.h"
#include "sculpt/skin/skin.h"

namespace sculpt::bench {
namespace {

using skin::OrientedBall;
using skin::Polyline2;
using skin::Skin;
using skin::Vec2;

constexpr double kDeg = std::numbers::pi / 180;

/// An admissible wavy chain: radii 0.5-1, gaps 1.1-2 times the radii, headings within 35 deg,
/// touching directions within 20 deg of the heading. Deterministic in `seed`.
std::vector<OrientedBall> Chain(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<OrientedBall> b;
  b.reserve(n);
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
    if (!b.empty() && !skin::CheckAdmissiblePair(b.size() - 1, b.back(), ball).ok()) continue;
    b.push_back(ball);
    c = nc;
    heading = h;
  }
  return b;
}

double PolylineLength(const Polyline2& p) {
  double l = 0;
  for (size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).Length();
  return l;
}

/// Draco point cloud of the points, sequential encoding (keeps the order), position quantised
/// so that Draco's step (bounding-box range / (2^bits - 1)) is no larger than `step`.
struct DracoResult {
  size_t bytes = 0;
  int bits = 0;
  double max_error = NAN;
  std::string error;
};
DracoResult DracoEncode(const Polyline2& pts, double step) {
  DracoResult r;
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (const Vec2& p : pts) {
    lo[0] = std::min(lo[0], p.x), hi[0] = std::max(hi[0], p.x);
    lo[1] = std::min(lo[1], p.y), hi[1] = std::max(hi[1], p.y);
  }
  const double range = std::max(hi[0] - lo[0], hi[1] - lo[1]);
  r.bits = 1;
  while (r.bits < 30 && range / (std::ldexp(1.0, r.bits) - 1) > step) ++r.bits;
  draco::PointCloudBuilder builder;
  builder.Start(static_cast<draco::PointIndex::ValueType>(pts.size()));
  const int att = builder.AddAttribute(draco::GeometryAttribute::POSITION, 2, draco::DT_FLOAT32);
  for (size_t i = 0; i < pts.size(); ++i) {
    // Relative to the box corner, so float32 does not add its own rounding to the comparison.
    const float v[2] = {static_cast<float>(pts[i].x - lo[0]), static_cast<float>(pts[i].y - lo[1])};
    builder.SetAttributeValueForPoint(att, draco::PointIndex(static_cast<uint32_t>(i)), v);
  }
  std::unique_ptr<draco::PointCloud> pc = builder.Finalize(false);
  draco::Encoder enc;
  enc.SetEncodingMethod(draco::POINT_CLOUD_SEQUENTIAL_ENCODING);
  enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, r.bits);
  enc.SetSpeedOptions(0, 0);  // best compression
  draco::EncoderBuffer buf;
  const draco::Status s = enc.EncodePointCloudToBuffer(*pc, &buf);
  if (!s.ok()) {
    r.error = s.error_msg_string();
    return r;
  }
  r.bytes = buf.size();
  draco::DecoderBuffer in;
  in.Init(buf.data(), buf.size());
  draco::Decoder dec;
  auto back = dec.DecodePointCloudFromBuffer(&in);
  if (back.ok()) {
    const draco::PointAttribute* a = back.value()->GetNamedAttribute(draco::GeometryAttribute::POSITION);
    r.max_error = 0;
    for (size_t i = 0; i < pts.size() && a; ++i) {
      float v[2];
      a->GetMappedValue(draco::PointIndex(static_cast<uint32_t>(i)), v);
      r.max_error = std::max(r.max_error, (Vec2{v[0] + lo[0], v[1] + lo[1]} - pts[i]).Length());
    }
  }
  return r;
}

}  // namespace

Json RunSkinBench(bool quick, const std::string& out_dat) {
  Json doc;
  const std::vector<size_t> sizes{1000, 10000, 100000};
  const int update_moves = quick ? 50 : 400;
  for (size_t n : sizes) {
    const auto balls = Chain(n, 20261122 + n);
    const int reps = n >= 100000 ? (quick ? 1 : 3) : (quick ? 2 : 7);
    Samples build;
    std::optional<Skin> skin;
    for (int r = 0; r < reps; ++r) {
      const auto t0 = Clock::now();
      auto s = Skin::Build(balls);
      build.Add(MsSince(t0));
      if (!s.ok()) return Json{{"error", s.status().ToString()}};
      skin.emplace(std::move(s).value());
    }
    const skin::SkinSummary sum = skin->Summary();
    // Moves of one ball by up to 0.1 radius, alternating back, at random places in the chain.
    std::mt19937_64 rng(n);
    Samples update;
    size_t refused = 0;
    for (int m = 0; m < update_moves; ++m) {
      const size_t i = rng() % n;
      OrientedBall b = skin->balls()[i];
      b.c = b.c + Vec2{0.05, (m % 2 ? -0.1 : 0.1)} * b.r;
      const auto t0 = Clock::now();
      auto c = skin->SetBall(i, b);
      const double us = 1000 * MsSince(t0);
      if (c.ok()) {
        update.Add(us);
      } else {
        ++refused;
      }
    }
    const std::string tag = n == 1000 ? "1e3" : n == 10000 ? "1e4" : "1e5";
    doc["build_ms_" + tag] = build.P(0.5);
    doc["update_us_" + tag] = update.P(0.5);
    doc["chains"].push_back({{"balls", n},
                             {"build_ms", build.Summary()},
                             {"build_us_per_ball", 1000 * build.P(0.5) / static_cast<double>(n)},
                             {"update_us", update.Summary()},
                             {"moves_refused", refused},
                             {"sections", sum.sections},
                             {"total_sections", sum.total},
                             {"simple_sections", sum.simple},
                             {"points", sum.points},
                             {"chord_tolerance", skin->chord_tolerance()}});
    Progress("skin: %zu balls: build p50 %.1f ms, update p50 %.1f us, %zu/%zu sections total", n,
             build.P(0.5), update.P(0.5), sum.total, sum.sections);
  }

  // Contour bytes: the 1e3-ball skin's snapshot at step = chord tolerance.
  {
    auto skin = Skin::Build(Chain(1000, 20261122 + 1000));
    const double tol = skin->chord_tolerance();
    const auto bytes = skin::EncodeSkinSnapshot(*skin);
    if (!bytes.ok()) return Json{{"error", bytes.status().ToString()}};
    skin::ContourView view;
    const Status applied = view.Apply(*bytes);
    if (!applied.ok()) return Json{{"error", applied.ToString()}};
    double max_err = 0;
    Polyline2 all;
    for (size_t k = 0; k < skin->sections().size(); ++k) {
      const skin::Section& s = skin->section(k);
      for (int side = 0; side < 2; ++side) {
        const Polyline2& a = side == 0 ? s.plus : s.minus;
        const Polyline2& b = side == 0 ? view.sections()[k].plus : view.sections()[k].minus;
        for (size_t i = 0; i < a.size(); ++i) max_err = std::max(max_err, (a[i] - b[i]).Length());
        all.insert(all.end(), a.begin(), a.end());
      }
    }
    const size_t float32 = all.size() * 2 * sizeof(float);
    const DracoResult draco = DracoEncode(all, tol);
    const auto skc1 = skin::internal::EncodeSkinSnapshotSkc1(*skin);
    if (!skc1.ok()) return Json{{"error", skc1.status().ToString()}};
    const auto skc2 = skin::internal::EncodeSkinSnapshotSkc2(*skin);
    if (!skc2.ok()) return Json{{"error", skc2.status().ToString()}};
    doc["contour_format"] = bytes->substr(0, 4);
    doc["contour_points"] = all.size();
    doc["contour_bytes"] = bytes->size();
    doc["contour_bytes_per_point"] = static_cast<double>(bytes->size()) / all.size();
    doc["contour_bits_per_point"] = 8.0 * static_cast<double>(bytes->size()) / all.size();
    // The previous formats (SKC2, SKC1) of the same snapshot, from the same binary.
    doc["contour_skc2_bytes"] = skc2->size();
    doc["contour_skc2_bits_per_point"] = 8.0 * static_cast<double>(skc2->size()) / all.size();
    doc["contour_skc2_ratio_vs_float32"] = static_cast<double>(float32) / skc2->size();
    doc["contour_skc1_bytes"] = skc1->size();
    doc["contour_skc1_bits_per_point"] = 8.0 * static_cast<double>(skc1->size()) / all.size();
    doc["contour_skc1_ratio_vs_float32"] = static_cast<double>(float32) / skc1->size();
    doc["contour_goal_ratio_vs_float32"] = 12;
    // The same chain sampled for the codec (SkinOptions::sample_for_codec, the default since the
    // codec restarts made it a function of the balls): SKC4's snapshot, its points, its decode
    // speed; and the chain sampled by curvature alone (the default before), whose points and
    // message the codec-sampled snapshot is compared with (the comparison at equal points).
    {
      skin::SkinOptions plain;
      plain.sample_for_codec = false;
      auto ps = Skin::Build(Chain(1000, 20261122 + 1000), plain);
      if (!ps.ok()) return Json{{"error", ps.status().ToString()}};
      size_t plain_points = 0;
      for (const auto& sec : ps->sections()) plain_points += sec.plus.size() + sec.minus.size();
      const auto pb = skin::EncodeSkinSnapshot(*ps);
      if (!pb.ok()) return Json{{"error", pb.status().ToString()}};
      doc["contour_curvature_sampler_points"] = plain_points;
      doc["contour_curvature_sampler_bytes"] = pb->size();
      skin::SkinOptions follow;
      follow.sample_for_codec = true;
      auto fs = Skin::Build(Chain(1000, 20261122 + 1000), follow);
      if (!fs.ok()) return Json{{"error", fs.status().ToString()}};
      const auto fb = skin::EncodeSkinSnapshot(*fs);
      if (!fb.ok()) return Json{{"error", fb.status().ToString()}};
      skin::ContourView fv;
      if (!fv.Apply(*fb).ok()) return Json{{"error", "codec-sampled snapshot not decoded"}};
      Polyline2 fall;
      double ferr = 0;
      for (size_t k = 0; k < fs->sections().size(); ++k) {
        for (int side = 0; side < 2; ++side) {
          const Polyline2& a = side == 0 ? fs->section(k).plus : fs->section(k).minus;
          const Polyline2& b = side == 0 ? fv.sections()[k].plus : fv.sections()[k].minus;
          for (size_t i = 0; i < a.size(); ++i) ferr = std::max(ferr, (a[i] - b[i]).Length());
          fall.insert(fall.end(), a.begin(), a.end());
        }
      }
      const DracoResult fdraco = DracoEncode(fall, tol);
      const auto fskc3 = skin::internal::EncodeSkinSnapshotSkc3(*fs);
      const double fbytes = static_cast<double>(fb->size());
      doc["contour_codec_sampled_format"] = fb->substr(0, 4);
      doc["contour_codec_sampled_points"] = fall.size();
      doc["contour_codec_sampled_bytes"] = fb->size();
      doc["contour_codec_sampled_bits_per_point"] = 8 * fbytes / static_cast<double>(fall.size());
      doc["contour_codec_sampled_ratio_vs_float32"] =
          static_cast<double>(fall.size() * 2 * sizeof(float)) / fbytes;
      doc["contour_codec_sampled_draco_bytes"] = fdraco.bytes;
      doc["contour_codec_sampled_ratio_vs_draco"] = static_cast<double>(fdraco.bytes) / fbytes;
      doc["contour_codec_sampled_skc3_bytes"] = fskc3.ok() ? fskc3->size() : 0;
      doc["contour_codec_sampled_max_error_over_tol"] = ferr / tol;
      doc["contour_codec_sampled_bits_per_curvature_point"] =
          8 * fbytes / static_cast<double>(plain_points);
      doc["contour_codec_sampled_ratio_vs_float32_at_curvature_points"] =
          static_cast<double>(plain_points * 2 * sizeof(float)) / fbytes;
      double best_f = INFINITY, best_d = INFINITY;
      for (int r = 0; r < (quick ? 5 : 40); ++r) {
        for (int f = 0; f < 2; ++f) {
          skin::ContourView v;
          const auto t0 = Clock::now();
          const Status st = v.Apply(f == 0 ? *fb : *bytes);
          (f == 0 ? best_f : best_d) = std::min(f == 0 ? best_f : best_d, MsSince(t0));
          if (!st.ok()) return Json{{"error", st.ToString()}};
        }
      }
      doc["decode_mpoints_per_s_codec_sampled"] = static_cast<double>(fall.size()) / 1000 / best_f;
      doc["decode_mpoints_per_s_default_alternating"] =
          static_cast<double>(all.size()) / 1000 / best_d;
      Progress("skin: codec-sampled contour %zu points: %zu bytes %s (SKC3 %zu), %.2f bits/point, "
               "max error %.3f tol, decode %.1f M points/s", fall.size(), fb->size(),
               fb->substr(0, 4).c_str(), fskc3.ok() ? fskc3->size() : 0,
               8 * fbytes / static_cast<double>(fall.size()), ferr / tol,
               doc["decode_mpoints_per_s_codec_sampled"].get<double>());
    }
    // The other road (issue 16, optional): the skin as its balls (centre, radius, touching
    // direction as float64), method byte and tolerance; a receiver with this library rebuilds
    // the very same points (the web client cannot). Its size, not a codec of its own here.
    const size_t balls_bytes = 4 + 1 + 8 + 2 + skin->balls().size() * 3 * sizeof(double);
    doc["skin_as_balls_bytes"] = balls_bytes;
    doc["skin_as_balls_ratio_vs_float32"] = static_cast<double>(float32) / balls_bytes;
    doc["contour_float32_bytes"] = float32;
    doc["contour_draco_bytes"] = draco.bytes;
    doc["contour_draco_bits"] = draco.bits;
    doc["contour_draco_max_error_over_tol"] = draco.max_error / tol;
    if (!draco.error.empty()) doc["contour_draco_error"] = draco.error;
    doc["contour_ratio_vs_float32"] = static_cast<double>(float32) / bytes->size();
    doc["contour_ratio_vs_draco"] = static_cast<double>(draco.bytes) / bytes->size();
    doc["contour_max_error_over_tol"] = max_err / tol;
    doc["contour_error_bound_over_tol"] = std::sqrt(0.5);  // step/sqrt(2), step = tol

    // Decode (and encode) speed over the whole snapshot, every format alternately, best of the
    // repeats (points per second; the figure the 50 M points/s goal is about).
    {
      double best[4] = {INFINITY, INFINITY, INFINITY, INFINITY};
      const std::string* forms[3] = {&*bytes, &*skc2, &*skc1};
      for (int r = 0; r < (quick ? 5 : 40); ++r) {
        auto t0 = Clock::now();
        (void)skin::EncodeSkinSnapshot(*skin);
        best[0] = std::min(best[0], MsSince(t0));
        for (int f = 0; f < 3; ++f) {
          skin::ContourView v;
          t0 = Clock::now();
          const Status st = v.Apply(*forms[f]);
          best[1 + f] = std::min(best[1 + f], MsSince(t0));
          if (!st.ok()) return Json{{"error", st.ToString()}};
        }
      }
      const double mp = static_cast<double>(all.size()) / 1000;  // points / ms / 1000 = M/s
      doc["encode_mpoints_per_s"] = mp / best[0];
      doc["decode_mpoints_per_s"] = mp / best[1];
      doc["decode_mpoints_per_s_skc2"] = mp / best[2];
      doc["decode_mpoints_per_s_skc1"] = mp / best[3];
      doc["decode_goal_mpoints_per_s"] = 50;
    }
    // One update after a move: its sections (the ball's two, and with sample_for_codec those
    // after them up to the next codec restart).
    OrientedBall b = skin->balls()[500];
    b.c.y += 0.05;
    auto change = skin->SetBall(500, b);
    if (change.ok()) {
      doc["contour_update_bytes"] = skin::EncodeSkinUpdate(*skin, *change)->size();
      doc["contour_update_sections"] = change->changed.size();
    }
    {
      // The same over 200 moves at random places: mean bytes and sections of an update.
      std::mt19937_64 rng(1000);
      Skin moved = *skin;
      size_t bytes = 0, sections = 0, moves = 0;
      for (int m = 0; m < 200; ++m) {
        const size_t i = rng() % moved.balls().size();
        OrientedBall mb = moved.balls()[i];
        mb.c = mb.c + Vec2{0.05, (m % 2 ? -0.1 : 0.1)} * mb.r;
        auto c = moved.SetBall(i, mb);
        if (!c.ok()) continue;
        auto u = skin::EncodeSkinUpdate(moved, *c);
        if (!u.ok()) continue;
        bytes += u->size();
        sections += c->changed.size();
        ++moves;
      }
      if (moves > 0) {
        doc["contour_update_bytes_mean"] = static_cast<double>(bytes) / static_cast<double>(moves);
        doc["contour_update_sections_mean"] =
            static_cast<double>(sections) / static_cast<double>(moves);
      }
    }

    // Encode / decode time for 2,000 points (the first polylines up to 2,000 points).
    std::vector<Polyline2> lines;
    size_t np = 0;
    for (const skin::Section& s : skin->sections()) {
      for (const Polyline2* p : {&s.plus, &s.minus}) {
        if (np >= 2000) break;
        Polyline2 q(p->begin(), p->begin() + std::min(p->size(), 2000 - np));
        np += q.size();
        lines.push_back(std::move(q));
      }
    }
    Samples enc, dec;
    std::string blob;
    for (int r = 0; r < (quick ? 20 : 200); ++r) {
      auto t0 = Clock::now();
      blob = *skin::EncodeContours(lines, tol);
      enc.Add(1000 * MsSince(t0));
      t0 = Clock::now();
      auto back = skin::DecodeContours(blob);
      dec.Add(1000 * MsSince(t0));
      if (!back.ok()) return Json{{"error", back.status().ToString()}};
    }
    doc["codec_points"] = np;
    doc["codec_bytes_2000"] = blob.size();
    doc["encode_us_per_2000_points"] = enc.P(0.5) * 2000.0 / static_cast<double>(np);
    doc["decode_us_per_2000_points"] = dec.P(0.5) * 2000.0 / static_cast<double>(np);
    Progress("skin: contour %zu points: %zu bytes %s (SKC2 %zu, SKC1 %zu, float32 %zu, draco %zu), "
             "max error %.3f tol, decode %.1f M points/s (SKC2 %.1f, SKC1 %.1f)",
             all.size(), bytes->size(), bytes->substr(0, 4).c_str(), skc2->size(), skc1->size(),
             float32, draco.bytes, max_err / tol, doc["decode_mpoints_per_s"].get<double>(),
             doc["decode_mpoints_per_s_skc2"].get<double>(),
             doc["decode_mpoints_per_s_skc1"].get<double>());
  }

  // What accuracy costs: chord tolerance from 1e-1 to 1e-5 of the smallest radius.
  {
    const auto balls = Chain(quick ? 50 : 200, 77);
    double min_r = INFINITY;
    for (const auto& b : balls) min_r = std::min(min_r, b.r);
    std::ofstream dat;
    if (!out_dat.empty()) {
      dat.open(out_dat);
      dat << "# rel_tol tol points points_per_unit_length bytes bytes_per_point build_ms "
             "max_error_over_tol total_sections sections\n";
    }
    bool smaller_than_draco = true;
    bool codec_sampled_smaller_than_draco = true;
    for (double rel : {1e-1, 1e-2, 1e-3, 1e-4, 1e-5}) {
      skin::SkinOptions o;
      o.chord_tolerance = rel * min_r;
      Samples t;
      std::optional<Skin> skin;
      for (int r = 0; r < (quick ? 1 : 5); ++r) {
        const auto t0 = Clock::now();
        auto s = Skin::Build(balls, o);
        t.Add(MsSince(t0));
        skin.emplace(std::move(s).value());
      }
      const skin::SkinSummary sum = skin->Summary();
      double length = 0;
      for (const auto& s : skin->sections()) length += PolylineLength(s.plus) + PolylineLength(s.minus);
      const auto bytes = skin::EncodeSkinSnapshot(*skin);
      skin::ContourView view;
      double max_err = 0;
      Polyline2 all;
      if (bytes.ok() && view.Apply(*bytes).ok()) {
        for (size_t k = 0; k < skin->sections().size(); ++k) {
          for (int side = 0; side < 2; ++side) {
            const auto& a = side == 0 ? skin->section(k).plus : skin->section(k).minus;
            const auto& b = side == 0 ? view.sections()[k].plus : view.sections()[k].minus;
            for (size_t i = 0; i < a.size(); ++i) {
              max_err = std::max(max_err, (a[i] - b[i]).Length());
            }
            all.insert(all.end(), a.begin(), a.end());
          }
        }
      }
      const DracoResult draco = DracoEncode(all, o.chord_tolerance);
      // The same chain sampled for the codec (SKC4): points and bytes, against Draco of its points.
      skin::SkinOptions of = o;
      of.sample_for_codec = true;
      auto fskin = Skin::Build(balls, of);
      size_t f_points = 0, f_bytes = 0;
      double f_err = 0;
      size_t f_draco = 0;
      if (fskin.ok()) {
        const auto fb = skin::EncodeSkinSnapshot(*fskin);
        skin::ContourView fv;
        if (fb.ok() && fv.Apply(*fb).ok()) {
          f_bytes = fb->size();
          Polyline2 fall;
          for (size_t k = 0; k < fskin->sections().size(); ++k) {
            for (int side = 0; side < 2; ++side) {
              const auto& a = side == 0 ? fskin->section(k).plus : fskin->section(k).minus;
              const auto& b = side == 0 ? fv.sections()[k].plus : fv.sections()[k].minus;
              for (size_t i = 0; i < a.size(); ++i) f_err = std::max(f_err, (a[i] - b[i]).Length());
              fall.insert(fall.end(), a.begin(), a.end());
            }
          }
          f_points = fall.size();
          f_draco = DracoEncode(fall, o.chord_tolerance).bytes;
        }
      }
      if (!(f_bytes > 0 && f_bytes < f_draco)) codec_sampled_smaller_than_draco = false;
      const auto skc1 = skin::internal::EncodeSkinSnapshotSkc1(*skin);
      const auto skc2 = skin::internal::EncodeSkinSnapshotSkc2(*skin);
      const double ours = bytes.ok() ? static_cast<double>(bytes->size()) : NAN;
      const double ppl = static_cast<double>(sum.points) / length;
      doc["accuracy"].push_back({{"rel_tol", rel},
                                 {"chord_tolerance", o.chord_tolerance},
                                 {"points", sum.points},
                                 {"points_per_unit_length", ppl},
                                 {"bytes", bytes.ok() ? bytes->size() : 0},
                                 {"bytes_per_point", bytes.ok() ? static_cast<double>(bytes->size()) / sum.points : NAN},
                                 {"build_ms", t.P(0.5)},
                                 {"bits_per_point", 8 * ours / static_cast<double>(all.size())},
                                 {"ratio_vs_float32", static_cast<double>(all.size() * 8) / ours},
                                 {"draco_bytes", draco.bytes},
                                 {"ratio_vs_draco", static_cast<double>(draco.bytes) / ours},
                                 {"skc2_bytes", skc2.ok() ? skc2->size() : 0},
                                 {"skc1_bytes", skc1.ok() ? skc1->size() : 0},
                                 {"format", bytes.ok() ? bytes->substr(0, 4) : ""},
                                 {"codec_sampled_points", f_points},
                                 {"codec_sampled_bytes", f_bytes},
                                 {"codec_sampled_draco_bytes", f_draco},
                                 {"codec_sampled_max_error_over_tol", f_err / o.chord_tolerance},
                                 {"max_error_over_tol", max_err / o.chord_tolerance},
                                 {"total_sections", sum.total},
                                 {"sections", sum.sections}});
      if (dat) {
        dat << rel << ' ' << o.chord_tolerance << ' ' << sum.points << ' ' << ppl << ' '
            << (bytes.ok() ? bytes->size() : 0) << ' '
            << (bytes.ok() ? static_cast<double>(bytes->size()) / sum.points : NAN) << ' '
            << t.P(0.5) << ' ' << max_err / o.chord_tolerance << ' ' << sum.total << ' '
            << sum.sections << '\n';
      }
      smaller_than_draco = smaller_than_draco && bytes.ok() && bytes->size() < draco.bytes;
      Progress("skin: tol %.0e r_min: %zu points, %.1f ms, %.0f bytes (draco %zu)", rel,
               sum.points, t.P(0.5), ours, draco.bytes);
    }
    doc["contour_smaller_than_draco_at_every_tolerance"] = smaller_than_draco;
    doc["contour_codec_sampled_smaller_than_draco_at_every_tolerance"] =
        codec_sampled_smaller_than_draco;
  }
  return doc;
}

}  // namespace sculpt::bench
