/// @brief `sculpt`: the command-line client. Subcommands: demo, info, export, thesis.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>

#include "demo.h"
#include "thesis_cmd.h"
#include "sculpt/levelset/sculpture.h"

int main(int argc, char** argv) {
  CLI::App app{"sculpt: the Sculpt command-line client"};
  app.require_subcommand(1);

  sculpt::client::DemoOptions demo;
  CLI::App* demo_cmd = app.add_subcommand(
      "demo", "Run the scripted sculpting session on the default scene and write its results");
  demo_cmd->add_option("--out", demo.out_dir, "Output folder")->capture_default_str();
  demo_cmd->add_option("--radius", demo.radius, "Sphere radius (world units)")
      ->check(CLI::Range(2.0, 200.0))
      ->capture_default_str();
  demo_cmd->add_option("--voxel-size", demo.voxel_size, "Voxel size (world units)")
      ->check(CLI::Range(0.05, 10.0))
      ->capture_default_str();
  demo_cmd->add_option("--strokes", demo.strokes, "Press samples in the scripted groove")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  demo_cmd->add_option("--seed", demo.seed, "Random seed for the stroke jitter")
      ->capture_default_str();

  std::string vdb_path;
  CLI::App* info_cmd = app.add_subcommand("info", "Print a .vdb sculpture's statistics");
  info_cmd->add_option("file", vdb_path, ".vdb file")->required()->check(CLI::ExistingFile);

  std::string export_in, export_out;
  double adaptivity = 0.0;
  CLI::App* export_cmd = app.add_subcommand("export", "Mesh a .vdb sculpture to OBJ or PLY");
  export_cmd->add_option("file", export_in, ".vdb file")->required()->check(CLI::ExistingFile);
  export_cmd->add_option("--out", export_out, "Output mesh (.obj or .ply)")->required();
  export_cmd->add_option("--adaptivity", adaptivity, "volumeToMesh adaptivity")
      ->check(CLI::Range(0.0, 1.0));

  CLI::App* thesis_cmd = app.add_subcommand(
      "thesis", "Rerun the thesis's 2D carve and compensation experiments; print JSON");

  CLI11_PARSE(app, argc, argv);

  if (*thesis_cmd) {
    std::printf("%s\n", sculpt::client::RunThesisReproduction().c_str());
    return 0;
  }

  if (*demo_cmd) {
    const sculpt::Status s = sculpt::client::RunDemo(demo);
    if (!s.ok()) {
      spdlog::error("demo failed: {}", s.ToString());
      return 1;
    }
    return 0;
  }
  if (*info_cmd) {
    auto s = sculpt::levelset::Sculpture::LoadVdb(vdb_path);
    if (!s.ok()) {
      spdlog::error("{}", s.status().ToString());
      return 1;
    }
    std::printf(
        "{\"name\": \"%s\", \"voxel_size\": %g, \"half_width\": %d, \"active_voxels\": %llu, "
        "\"volume\": %.6f, \"reference_volume\": %.6f, \"state_hash\": \"%016llx\"}\n",
        s->name().c_str(), s->voxel_size(), s->half_width(),
        static_cast<unsigned long long>(s->ActiveVoxelCount()), s->volume(),
        s->reference_volume(), static_cast<unsigned long long>(s->StateHash()));
    return 0;
  }
  if (*export_cmd) {
    auto s = sculpt::levelset::Sculpture::LoadVdb(export_in);
    if (!s.ok()) {
      spdlog::error("{}", s.status().ToString());
      return 1;
    }
    auto m = s->ExportMesh(export_out, adaptivity);
    if (!m.ok()) {
      spdlog::error("{}", m.status().ToString());
      return 1;
    }
    spdlog::info("wrote {}: {} vertices, {} triangles", export_out, m->vertices, m->triangles);
    return 0;
  }
  return 0;
}
