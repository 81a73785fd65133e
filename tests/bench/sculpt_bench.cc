/// @brief sculpt-bench: benchmarks of the sculpting kernel. Progress goes to stderr, the JSON
/// document to stdout. Benchmarks, not timed tests: nothing here fails on a slow machine.
///
///   sculpt-bench edit --json       per-edit latency vs object size, naive pipeline, volume drift
///   sculpt-bench accuracy --json   accuracy vs time over schemes, voxel sizes, policies
///   sculpt-bench skin --json       ball skins: build/update time, contour bytes, accuracy cost
///   sculpt-bench haptics --json    haptic tick cost (penalty/proxy, 32/128/512 samples), 1 kHz loop
///   sculpt-bench hetero --json     hyperpatch validity per cell and per 1,000 cells, edits, inverse map
///   sculpt-bench undo --json       per-user undo latency under 0/10/30 later strokes, memory per step
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <string>

#include "bench_common.h"

namespace sculpt::bench {
Json RunSkinBench(bool quick, const std::string& out_dat);  // skin_bench.cc
Json RunHapticsBench(bool quick);                           // haptics_bench.cc
Json RunHeteroBench(bool quick, const std::string& write_scenes);  // hetero_bench.cc
#ifdef SCULPT_BENCH_UNDO
Json RunUndoBench(bool quick, double radius, int trials, uint64_t seed);  // undo_bench.cc
#endif
}  // namespace sculpt::bench

namespace {

using sculpt::bench::Json;

std::string CommandLine(int argc, char** argv) {
  std::string s;
  for (int i = 0; i < argc; ++i) {
    if (i) s += ' ';
    s += argv[i];
  }
  return s;
}

double Num(const Json& j, const char* a, const char* b = nullptr) {
  const Json* p = &j;
  if (!p->contains(a)) return NAN;
  p = &(*p)[a];
  if (b) {
    if (!p->contains(b)) return NAN;
    p = &(*p)[b];
  }
  return p->is_number() ? p->get<double>() : NAN;
}

void PrintEditSummary(const Json& d) {
  std::printf("%-8s %-17s %10s %10s %10s\n", "radius", "kind", "p50 ms", "p99 ms", "mean ms");
  for (const Json& r : d["radii"]) {
    for (const char* k : {"press", "add", "subtract", "press_equal_work", "inflate", "deflate"}) {
      if (!r.contains(k)) continue;
      std::printf("%-8g %-17s %10.3f %10.3f %10.3f\n", r["radius_voxels"].get<double>(), k,
                  Num(r[k], "wall_ms", "p50"), Num(r[k], "wall_ms", "p99"),
                  Num(r[k], "wall_ms", "mean"));
    }
  }
  for (const Json& n : d["naive"]) {
    std::printf("naive r=%g: p50 %.1f ms\n", n["radius_voxels"].get<double>(),
                Num(n, "total_ms", "p50"));
  }
  std::printf("size_independence_p99_ratio %.3f (goal <= 1.25)\n",
              Num(d, "size_independence_p99_ratio"));
  std::printf("speedup_vs_naive_p50        %.1f (goal >= 300)\n", Num(d, "speedup_vs_naive_p50"));
  std::printf("volume_drift_rel            %.3g (goal <= 5e-4)\n", Num(d, "volume_drift_rel"));
}

void PrintAccuracySummary(const Json& d) {
  std::printf("%-16s %8s %10s %12s %12s %12s\n", "config", "voxel", "ms/edit", "shape mean",
              "shape max", "vol err");
  for (const Json& r : d["configurations"]) {
    std::printf("%-16s %8g %10.2f %12.5f %12.5f %12.3g\n", r["label"].get<std::string>().c_str(),
                Num(r, "voxel_size"), Num(r, "ms_per_edit"), Num(r, "shape_error_mean"),
                Num(r, "shape_error_max"), Num(r, "volume_error_rel"));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sculpt-bench: benchmarks of the Sculpt level-set kernel (JSON on stdout, "
               "progress on stderr)"};
  app.require_subcommand(1);
  bool json = false;

  sculpt::bench::EditBenchOptions eo;
  CLI::App* edit = app.add_subcommand(
      "edit", "per-edit p50/p99 (press, add, subtract) vs sphere radius, the naive whole-grid "
              "OpenVDB pipeline, and volume drift over a long run of press strokes");
  edit->add_flag("--json", json, "print the JSON document (otherwise a short table)");
  edit->add_flag("--quick", eo.quick, "seconds-long smoke configuration");
  edit->add_option("--radii", eo.radii, "sphere radii in voxels")->delimiter(',');
  edit->add_option("--edits", eo.edits, "timed edits per kind per radius")->check(CLI::Range(1, 1000000));
  edit->add_option("--warmup", eo.warmup, "untimed edits per kind per radius")->check(CLI::Range(0, 1000));
  edit->add_option("--naive-radii", eo.naive_radii, "radii for the naive pipeline")->delimiter(',');
  edit->add_option("--naive-edits", eo.naive_edits, "naive edits per radius (0: skip)")->check(CLI::Range(0, 1000));
  edit->add_option("--kinds", eo.kinds,
                   "edit kinds to run: press, stroke (4-pose batches), add, subtract, press_equal_work, inflate, deflate "
                   "(default: all)");
  edit->add_option("--strokes", eo.strokes, "press strokes of the volume-drift run (0: skip)")->check(CLI::Range(0, 10000000));
  edit->add_option("--stroke-radius", eo.stroke_radius, "sphere radius of the volume-drift run");
  edit->add_option("--checkpoint-every", eo.checkpoint_every, "volume checkpoint interval (strokes)")->check(CLI::Range(1, 10000000));
  edit->add_option("--tool-radius", eo.tool_radius, "tool radius in voxels");
  edit->add_option("--penetration", eo.penetration, "tool penetration in voxels");
  edit->add_option("--seed", eo.seed, "random seed");
  edit->add_flag("--repair-band-every-edit", eo.repair_band_every_edit,
                 "scan every edit's block for slivers and a torn band and rebuild it "
                 "(EditSettings::repair_band_every_edit)");

  sculpt::bench::AccuracyBenchOptions ao;
  CLI::App* acc = app.add_subcommand(
      "accuracy", "time vs accuracy over voxel size, spatial and temporal scheme, reinit policy "
                  "and compensation method on a fixed press scenario");
  acc->add_flag("--json", json, "print the JSON document (otherwise a short table)");
  acc->add_flag("--quick", ao.quick, "seconds-long smoke configuration");
  acc->add_option("--out-dat", ao.out_dat, "also write the table as gnuplot data");
  acc->add_option("--strokes", ao.strokes, "press samples in the scenario")->check(CLI::Range(1, 100000));
  acc->add_option("--repeats", ao.repeats, "runs of the scenario per configuration (timing median)")->check(CLI::Range(1, 100));
  acc->add_option("--base-voxel", ao.base_voxel, "voxel size of the scheme/policy sweeps");
  acc->add_option("--voxel-sizes", ao.voxel_sizes, "voxel sizes of the voxel-size sweep")->delimiter(',');
  acc->add_option("--reference-voxel", ao.reference_voxel, "voxel size of the reference run");
  bool one_factor = false;
  acc->add_flag("--one-factor", one_factor,
                "vary the schemes one factor at a time instead of the full spatial x temporal grid");

  bool skin_quick = false;
  std::string skin_dat;
  CLI::App* skin = app.add_subcommand(
      "skin", "ball skins: build time for 1e3-1e5 balls, update time after one move, contour "
              "bytes vs float32 and Draco, codec speed, chord tolerance vs points/bytes/time");
  skin->add_flag("--json", json, "print the JSON document (the only output of skin)");
  skin->add_flag("--quick", skin_quick, "seconds-long smoke configuration");
  skin->add_option("--out-dat", skin_dat, "also write the accuracy table as gnuplot data");

  bool haptics_quick = false;
  CLI::App* haptics = app.add_subcommand(
      "haptics", "haptic tick cost p50/p99/p99.9/max for the penalty and proxy models at 32, 128 "
                 "and 512 tool samples on a radius-128 sphere; the 1 kHz loop's rate, period "
                 "error and snapshot lag while snapshots are swapped at 120 Hz");
  haptics->add_flag("--json", json, "print the JSON document (the only output of haptics)");
  haptics->add_flag("--quick", haptics_quick, "seconds-long smoke configuration");

  bool hetero_quick = false;
  std::string hetero_scenes;
  CLI::App* hetero = app.add_subcommand(
      "hetero", "heterogeneous hyperpatches: validity check time per cell and for a 1,000-cell "
                "model, intent edits, inverse-map point location, model size");
  hetero->add_flag("--json", json, "print the JSON document (the only output of hetero)");
  hetero->add_flag("--quick", hetero_quick, "seconds-long smoke configuration");
  hetero->add_option("--write-scenes", hetero_scenes,
                     "write the example models (tyre, mechanical part) into this directory");

#ifdef SCULPT_BENCH_UNDO
  bool undo_quick = false;
  double undo_radius = 128;
  int undo_trials = 30;
  uint64_t undo_seed = 15;
  CLI::App* undo = app.add_subcommand(
      "undo", "per-user undo (issue 15): undo latency p50/p99 with 0, 10 and 30 later "
              "overlapping strokes by others, the cost of recording an edit, memory per step");
  undo->add_flag("--json", json, "print the JSON document (the only output of undo)");
  undo->add_flag("--quick", undo_quick, "seconds-long smoke configuration");
  undo->add_option("--radius", undo_radius, "sphere radius in voxels")->check(CLI::Range(16.0, 512.0));
  undo->add_option("--trials", undo_trials, "undos timed per configuration")->check(CLI::Range(1, 10000));
  undo->add_option("--seed", undo_seed, "random seed");
#endif

  CLI11_PARSE(app, argc, argv);
  const std::string cmd = CommandLine(argc, argv);

  Json doc;
  bool json_only = false;
#ifdef SCULPT_BENCH_UNDO
  if (*undo) {
    doc = sculpt::bench::RunUndoBench(undo_quick, undo_radius, undo_trials, undo_seed);
    json_only = true;
  } else
#endif
  if (*hetero) {
    doc = sculpt::bench::RunHeteroBench(hetero_quick, hetero_scenes);
  } else if (*haptics) {
    doc = sculpt::bench::RunHapticsBench(haptics_quick);
  } else if (*skin) {
    doc = sculpt::bench::RunSkinBench(skin_quick, skin_dat);
  } else if (*edit) {
    if (eo.quick) {
      // Seconds long: two small spheres, few edits, a short stroke run. The ratios then use the
      // radii that ran (see "ratios" in the output).
      if (edit->count("--radii") == 0) eo.radii = {24, 48};
      if (edit->count("--edits") == 0) eo.edits = 20;
      if (edit->count("--warmup") == 0) eo.warmup = 2;
      if (edit->count("--naive-radii") == 0) eo.naive_radii = {48};
      if (edit->count("--naive-edits") == 0) eo.naive_edits = 1;
      if (edit->count("--strokes") == 0) eo.strokes = 300;
      if (edit->count("--stroke-radius") == 0) eo.stroke_radius = 32;
      if (edit->count("--checkpoint-every") == 0) eo.checkpoint_every = 100;
    }
    doc = sculpt::bench::RunEditBench(eo);
  } else {
    ao.scheme_grid = !one_factor;
    if (ao.quick) {
      if (acc->count("--strokes") == 0) ao.strokes = 6;
      if (acc->count("--repeats") == 0) ao.repeats = 1;
      if (acc->count("--base-voxel") == 0) ao.base_voxel = 1.0;
      if (acc->count("--voxel-sizes") == 0) ao.voxel_sizes = {1.0, 0.5};
      if (acc->count("--reference-voxel") == 0) ao.reference_voxel = 0.25;
      if (!one_factor) ao.scheme_grid = false;
    }
    doc = sculpt::bench::RunAccuracyBench(ao);
  }
  Json out{{"command", cmd}};
  out.update(doc);
  doc = std::move(out);
  if (json || json_only || *skin || *haptics || *hetero) {
    std::cout << doc.dump(2) << std::endl;
  } else if (*edit) {
    PrintEditSummary(doc);
  } else {
    PrintAccuracySummary(doc);
  }
  return doc.contains("error") ? 1 : 0;
}
