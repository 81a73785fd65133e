/// @brief `sculpt thesis`: the thesis's 2D experiments through the production kernels.
#include "thesis_cmd.h"

#include <chrono>
#include <nlohmann/json.hpp>

#include "sculpt/levelset/thesis_repro.h"

namespace sculpt::client {

using levelset::thesis::CarveSetup;
using levelset::thesis::CompensationForm;
using levelset::thesis::CompensationSetup;

std::string RunThesisReproduction() {
  nlohmann::json carve = nlohmann::json::array();
  // Seed 000 §3.2 tables (Figs. 6.13-6.28) and the digest's REPRO of the removed areas.
  struct CarveCase {
    const char* tool;
    double dt;
    int thesis_iterations;
  };
  const CarveCase cases[] = {{"circle", 1.0, 4},  {"circle", 0.1, 13}, {"circle", 0.01, 97},
                             {"square", 1.0, 3},  {"square", 0.1, 7},  {"square", 0.01, 55}};
  for (const CarveCase& c : cases) {
    CarveSetup setup;
    setup.tool = std::string(c.tool) == "circle" ? levelset::thesis::ThesisCircleTool()
                                                 : levelset::thesis::ThesisSquareTool();
    setup.dt = c.dt;
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = levelset::thesis::RunLocalCarve(setup);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    carve.push_back({{"tool", c.tool},
                     {"dt", c.dt},
                     {"thesis_iterations", c.thesis_iterations},
                     {"iterations", r.thesis_iterations},
                     {"area_removed", r.area_removed},
                     {"island_area", r.island_area},
                     {"ms", ms}});
  }
  nlohmann::json comp = nlohmann::json::array();
  struct CompCase {
    const char* form;
    double dt;
    const char* thesis;
  };
  // Seed 000 §3.3 (Figs. 6.33-6.44): delta stalls at 2; |grad| unstable at 1 and 0.1, 0.5 at 0.01.
  const CompCase ccases[] = {{"delta", 1.0, "stalls at 2"},
                             {"gradient", 1.0, "unstable"},
                             {"gradient", 0.1, "unstable"},
                             {"gradient", 0.01, "final |error| 0.5"}};
  for (const CompCase& c : ccases) {
    CompensationSetup setup;
    setup.form = std::string(c.form) == "delta" ? CompensationForm::kDelta
                                                : CompensationForm::kGradient;
    setup.dt = c.dt;
    const auto r = levelset::thesis::RunCompensation(setup);
    comp.push_back({{"form", c.form},
                    {"dt", c.dt},
                    {"thesis", c.thesis},
                    {"diverged", r.diverged},
                    {"stalled", r.stalled},
                    {"oscillating", r.oscillating},
                    {"final_abs_dif", r.final_abs_dif},
                    {"dif_history", r.dif_history}});
  }
  nlohmann::json doc = {{"source", "seed 000, chapter 6 (2D, h = 0.5, 201x201 nodes)"},
                        {"local_carve", carve},
                        {"volume_compensation", comp}};
  return doc.dump(2);
}

}  // namespace sculpt::client
