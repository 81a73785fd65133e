/// @brief `sculpt skin`: the ball file, the report, the point lists.
#include "skin_cmd.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>

#include "sculpt/skin/contour_codec.h"
#include "sculpt/skin/skin.h"

namespace sculpt::client {
namespace {

using nlohmann::ordered_json;
using sculpt::skin::OrientedBall;
using sculpt::skin::Polyline2;

const char* const kUsage = "skin";

/// A JSON number as double; "field must be a number" otherwise.
Status Number(const ordered_json& j, const std::string& field, double* out) {
  if (!j.is_number()) return InvalidArgument(field + " must be a number");
  *out = j.get<double>();
  return Status::Ok();
}

Status Pair(const ordered_json& j, const std::string& field, double* x, double* y) {
  if (!j.is_array() || j.size() != 2) return InvalidArgument(field + " must be [x, y]");
  SCULPT_RETURN_IF_ERROR(Number(j[0], field + "[0]", x));
  return Number(j[1], field + "[1]", y);
}

Status ParseBall(const ordered_json& j, const std::string& field, OrientedBall* b) {
  if (!j.is_object()) return InvalidArgument(field + " must be an object");
  if (!j.contains("c")) return InvalidArgument(field + ".c missing (centre [x, y])");
  if (!j.contains("r")) return InvalidArgument(field + ".r missing (radius)");
  SCULPT_RETURN_IF_ERROR(Pair(j["c"], field + ".c", &b->c.x, &b->c.y));
  SCULPT_RETURN_IF_ERROR(Number(j["r"], field + ".r", &b->r));
  const int given = j.contains("theta") + j.contains("theta_deg") + j.contains("dir");
  if (given != 1) {
    return InvalidArgument(field + ": give exactly one of theta (radians), theta_deg, dir [x, y]");
  }
  if (j.contains("theta")) {
    SCULPT_RETURN_IF_ERROR(Number(j["theta"], field + ".theta", &b->theta));
  } else if (j.contains("theta_deg")) {
    double deg = 0;
    SCULPT_RETURN_IF_ERROR(Number(j["theta_deg"], field + ".theta_deg", &deg));
    b->theta = deg * std::numbers::pi / 180;
  } else {
    double x = 0, y = 0;
    SCULPT_RETURN_IF_ERROR(Pair(j["dir"], field + ".dir", &x, &y));
    if (!std::isfinite(x) || !std::isfinite(y) || std::hypot(x, y) == 0) {
      return InvalidArgument(field + ".dir=(" + std::to_string(x) + ", " + std::to_string(y) +
                             ") must be a finite non-zero vector");
    }
    b->theta = std::atan2(y, x);
  }
  return Status::Ok();
}

ordered_json Points(const Polyline2& p) {
  ordered_json a = ordered_json::array();
  for (const auto& v : p) a.push_back({v.x, v.y});
  return a;
}

ordered_json Finite(double v) { return std::isfinite(v) ? ordered_json(v) : ordered_json(nullptr); }

ordered_json Report(const sculpt::skin::Skin& s) {
  ordered_json sections = ordered_json::array();
  for (size_t k = 0; k < s.sections().size(); ++k) {
    const auto& sec = s.section(k);
    const auto& r = sec.report;
    ordered_json sides = ordered_json::object();
    for (int i = 0; i < 2; ++i) {
      const auto& sr = r.side[i];
      sides[i == 0 ? "+" : "-"] = {{"offset_pieces", sr.offset_pieces},
                                   {"aspline_pieces", sr.aspline_pieces},
                                   {"min_one_plus_kd", Finite(sr.min_one_plus_kd)},
                                   {"self_intersections", sr.self_intersections},
                                   {"clearance", Finite(sr.clearance)},
                                   {"points", i == 0 ? sec.plus.size() : sec.minus.size()}};
    }
    ordered_json hidden = ordered_json::array();
    for (const auto& h : r.hidden) {
      hidden.push_back({{"c", {h.c.x, h.c.y}}, {"r", h.r}, {"theta", h.theta}});
    }
    sections.push_back({{"section", k},
                        {"balls", {k, k + 1}},
                        {"id", sec.id},
                        {"total", r.total},
                        {"simple", r.simple},
                        {"mother_regular", r.mother_regular},
                        {"clearance", Finite(r.clearance)},
                        {"sides", sides},
                        {"hidden_balls", hidden},
                        {"notes", r.notes}});
  }
  const auto sum = s.Summary();
  return {{"method", sculpt::skin::MethodName(s.options().method)},
          {"chord_tolerance", s.chord_tolerance()},
          {"balls", s.balls().size()},
          {"sections", sum.sections},
          {"total_sections", sum.total},
          {"simple_sections", sum.simple},
          {"all_total", sum.all_total()},
          {"points", sum.points},
          {"min_clearance", Finite(sum.min_clearance)},
          {"section_reports", sections}};
}

}  // namespace

const char* const kSkinFileHelp = R"(Ball file (JSON):
  {"method": "hybrid", "tolerance": 0.001,            (both optional; flags override)
   "balls": [{"c": [0, 0], "r": 1, "theta_deg": 30},  (theta in radians, theta_deg, or
             {"c": [4, 0], "r": 1, "dir": [1, 0.5]}]}   dir [x, y]: the touching direction)
  A bare array of balls is accepted too. At least two balls; consecutive balls must be
  admissible (no contact point inside the neighbour). Prints the per-section validation report
  (JSON) on stdout. --out-json writes the point lists (+ chain, - chain, closed outline, per
  section), --out-bin the binary contour snapshot (see sculpt/skin/contour_codec.h).)";

CLI::App* AddSkinCommand(CLI::App& app, SkinCmdOptions& o) {
  CLI::App* cmd = app.add_subcommand(
      kUsage, "Build the G1 skin of a chain of oriented 2D balls; print its validation report");
  cmd->footer(kSkinFileHelp);
  cmd->add_option("--balls", o.balls, "Ball file (JSON; format below)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--method", o.method, "naive | offset | hybrid (default: the file's, else hybrid)")
      ->check(CLI::IsMember({"naive", "offset", "hybrid"}));
  cmd->add_option("--tolerance", o.tolerance,
                  "Chord tolerance (default: the file's, else 1e-3 of the smallest radius)")
      ->check(CLI::Range(0.0, 1e12));
  cmd->add_option("--out-json", o.out_json, "Write the point lists as JSON");
  cmd->add_option("--out-bin", o.out_bin, "Write the binary contour snapshot");
  return cmd;
}

int RunSkin(const SkinCmdOptions& o) {
  std::ifstream in(o.balls);
  if (!in) {
    spdlog::error("skin: cannot read {}", o.balls);
    return 1;
  }
  ordered_json doc;
  try {
    doc = ordered_json::parse(in);
  } catch (const std::exception& e) {
    spdlog::error("skin: {} is not JSON: {}", o.balls, e.what());
    return 2;
  }
  auto fail = [&](const Status& s) {
    spdlog::error("skin: {}: {}", o.balls, s.message());
    return 2;
  };
  const ordered_json* list = &doc;
  sculpt::skin::SkinOptions opt;
  if (doc.is_object()) {
    if (!doc.contains("balls")) return fail(InvalidArgument("balls missing"));
    list = &doc["balls"];
    if (doc.contains("method")) {
      if (!doc["method"].is_string()) return fail(InvalidArgument("method must be a string"));
      auto m = sculpt::skin::ParseMethod(doc["method"].get<std::string>());
      if (!m.ok()) return fail(m.status());
      opt.method = *m;
    }
    if (doc.contains("tolerance")) {
      if (const Status s = Number(doc["tolerance"], "tolerance", &opt.chord_tolerance); !s.ok()) {
        return fail(s);
      }
    }
  }
  if (!list->is_array()) return fail(InvalidArgument("balls must be an array"));
  std::vector<OrientedBall> balls(list->size());
  for (size_t i = 0; i < list->size(); ++i) {
    if (const Status s = ParseBall((*list)[i], "balls[" + std::to_string(i) + "]", &balls[i]);
        !s.ok()) {
      return fail(s);
    }
  }
  if (!o.method.empty()) opt.method = *sculpt::skin::ParseMethod(o.method);
  if (o.tolerance > 0) opt.chord_tolerance = o.tolerance;
  auto skin = sculpt::skin::Skin::Build(std::move(balls), opt);
  if (!skin.ok()) return fail(skin.status());

  std::printf("%s\n", Report(*skin).dump(2).c_str());
  if (!o.out_json.empty()) {
    ordered_json sections = ordered_json::array();
    for (const auto& s : skin->sections()) {
      sections.push_back({{"id", s.id}, {"plus", Points(s.plus)}, {"minus", Points(s.minus)}});
    }
    const ordered_json out = {{"chord_tolerance", skin->chord_tolerance()},
                              {"plus", Points(skin->Chain(1))},
                              {"minus", Points(skin->Chain(-1))},
                              {"outline", Points(skin->Outline())},
                              {"sections", sections}};
    std::ofstream f(o.out_json);
    f << out.dump() << "\n";
    if (!f) {
      spdlog::error("skin: cannot write {}", o.out_json);
      return 1;
    }
  }
  if (!o.out_bin.empty()) {
    auto bytes = sculpt::skin::EncodeSkinSnapshot(*skin);
    if (!bytes.ok()) return fail(bytes.status());
    std::ofstream f(o.out_bin, std::ios::binary);
    f.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
    if (!f) {
      spdlog::error("skin: cannot write {}", o.out_bin);
      return 1;
    }
    spdlog::info("wrote {}: {} bytes for {} points", o.out_bin, bytes->size(),
                 skin->Summary().points);
  }
  return 0;
}

}  // namespace sculpt::client
