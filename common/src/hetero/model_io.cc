/// @brief JSON model files for composite heterogeneous hyperpatches.
#include "sculpt/hetero/model_io.h"

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sculpt/core/check.h"

namespace sculpt::hetero {
namespace {

using Json = nlohmann::json;

Status NeedArray(const Json& j, const std::string& field) {
  if (!j.is_array()) return InvalidArgument(field + " is not an array");
  return Status::Ok();
}

StatusOr<double> NumberAt(const Json& j, const std::string& field) {
  if (!j.is_number()) return InvalidArgument(field + " is not a number");
  return j.get<double>();
}

}  // namespace

std::string ModelToJson(const CompositeModel& model, const std::string& name,
                        const std::string& description) {
  Json doc;
  doc["format"] = kModelFormat;
  doc["version"] = 1;
  if (!name.empty()) doc["name"] = name;
  if (!description.empty()) doc["description"] = description;
  Json mats = Json::array();
  for (const MaterialInfo& m : model.material_info()) {
    mats.push_back({{"name", m.name}, {"colour", m.colour}});
  }
  doc["materials"] = mats;
  Json corners = Json::array();
  for (const auto& [q, f] : model.all_corner_flags()) {
    corners.push_back({{"coefficient", q}, {"geometry_c1", f.geometry_c1},
                       {"material_c1", f.material_c1}});
  }
  doc["corners"] = std::move(corners);
  // One coefficient and one cell per line: readable, and a diff of an edited model stays small.
  std::string head = doc.dump(1);
  head.pop_back();  // the closing brace
  while (!head.empty() && (head.back() == '\n' || head.back() == ' ')) head.pop_back();
  std::string out = head + ",\n \"coefficients\": [";
  for (uint32_t q = 0; q < model.coefficient_count(); ++q) {
    Json c = Json::array({model.position(q).x, model.position(q).y, model.position(q).z});
    for (double a : model.fractions(q)) c.push_back(a);
    out += (q ? ",\n  " : "\n  ") + c.dump();
  }
  out += "\n ],\n \"cells\": [";
  for (size_t c = 0; c < model.cell_count(); ++c) {
    out += (c ? ",\n  " : "\n  ") + Json(model.cell(static_cast<int>(c)).coef).dump();
  }
  out += "\n ]\n}";
  return out;
}


StatusOr<CompositeModel> ModelFromJson(const std::string& text, size_t max_cells) {
  Json doc = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return InvalidArgument("model: not valid JSON");
  if (!doc.is_object()) return InvalidArgument("model: top level is not an object");
  if (!doc.contains("format") || doc["format"] != kModelFormat) {
    return InvalidArgument(std::string("model.format is not \"") + kModelFormat + "\"");
  }
  if (!doc.contains("version") || doc["version"] != 1) {
    return InvalidArgument("model.version outside [1, 1]");
  }
  if (!doc.contains("materials")) return InvalidArgument("model.materials is missing");
  SCULPT_RETURN_IF_ERROR(NeedArray(doc["materials"], "model.materials"));
  std::vector<MaterialInfo> mats;
  const Json& jm = doc["materials"];
  SCULPT_RETURN_IF_ERROR(CheckRange("model.materials.size", static_cast<double>(jm.size()), 1,
                                    kMaxMaterials));
  for (size_t i = 0; i < jm.size(); ++i) {
    const std::string f = "model.materials[" + std::to_string(i) + "]";
    MaterialInfo m;
    if (!jm[i].is_object() || !jm[i].contains("name") || !jm[i]["name"].is_string()) {
      return InvalidArgument(f + ".name is missing or not a string");
    }
    m.name = jm[i]["name"].get<std::string>();
    if (jm[i].contains("colour")) {
      SCULPT_RETURN_IF_ERROR(NeedArray(jm[i]["colour"], f + ".colour"));
      if (jm[i]["colour"].size() != 3) return InvalidArgument(f + ".colour.size outside [3, 3]");
      for (size_t c = 0; c < 3; ++c) {
        SCULPT_ASSIGN_OR_RETURN(m.colour[c],
                                NumberAt(jm[i]["colour"][c], f + ".colour[" + std::to_string(c) + "]"));
      }
    }
    mats.push_back(std::move(m));
  }
  SCULPT_ASSIGN_OR_RETURN(CompositeModel model, CompositeModel::Create(std::move(mats)));
  const int n = model.materials();

  if (!doc.contains("coefficients")) return InvalidArgument("model.coefficients is missing");
  const Json& jc = doc["coefficients"];
  SCULPT_RETURN_IF_ERROR(NeedArray(jc, "model.coefficients"));
  SCULPT_RETURN_IF_ERROR(CheckRange("model.coefficients.size", static_cast<double>(jc.size()), 0,
                                    64.0 * static_cast<double>(max_cells)));
  std::vector<double> a(static_cast<size_t>(n));
  for (size_t q = 0; q < jc.size(); ++q) {
    const std::string f = "model.coefficients[" + std::to_string(q) + "]";
    SCULPT_RETURN_IF_ERROR(NeedArray(jc[q], f));
    if (jc[q].size() != static_cast<size_t>(3 + n)) {
      return Outside(f + ".size", std::to_string(jc[q].size()),
                     std::string("[") + std::to_string(3 + n) + ", " + std::to_string(3 + n) + "]");
    }
    Vec3 p;
    SCULPT_ASSIGN_OR_RETURN(p.x, NumberAt(jc[q][0], f + "[0]"));
    SCULPT_ASSIGN_OR_RETURN(p.y, NumberAt(jc[q][1], f + "[1]"));
    SCULPT_ASSIGN_OR_RETURN(p.z, NumberAt(jc[q][2], f + "[2]"));
    SCULPT_RETURN_IF_ERROR(CheckFinitePoint(f + ".p", p));
    for (int m = 0; m < n; ++m) {
      SCULPT_ASSIGN_OR_RETURN(a[static_cast<size_t>(m)],
                              NumberAt(jc[q][static_cast<size_t>(3 + m)], f + "[" + std::to_string(3 + m) + "]"));
    }
    SCULPT_RETURN_IF_ERROR(ValidateFractions(f + ".a", a, n));
    SCULPT_RETURN_IF_ERROR(model.AddCoefficient(p, a).status());
  }

  if (!doc.contains("cells")) return InvalidArgument("model.cells is missing");
  const Json& jcells = doc["cells"];
  SCULPT_RETURN_IF_ERROR(NeedArray(jcells, "model.cells"));
  SCULPT_RETURN_IF_ERROR(CheckRange("model.cells.size", static_cast<double>(jcells.size()), 0,
                                    static_cast<double>(max_cells)));
  for (size_t c = 0; c < jcells.size(); ++c) {
    const std::string f = "model.cells[" + std::to_string(c) + "]";
    SCULPT_RETURN_IF_ERROR(NeedArray(jcells[c], f));
    if (jcells[c].size() != 64) {
      return Outside(f + ".size", std::to_string(jcells[c].size()), "[64, 64]");
    }
    std::array<uint32_t, 64> idx{};
    for (size_t s = 0; s < 64; ++s) {
      const Json& v = jcells[c][s];
      if (!v.is_number_integer() || v.get<int64_t>() < 0 ||
          v.get<int64_t>() >= static_cast<int64_t>(model.coefficient_count())) {
        return Outside(f + "[" + std::to_string(s) + "]", v.dump(),
                       std::string("[0, ") +
                           std::to_string(static_cast<long long>(model.coefficient_count()) - 1) +
                           "]");
      }
      idx[s] = static_cast<uint32_t>(v.get<int64_t>());
    }
    SCULPT_RETURN_IF_ERROR(model.AddCell(idx).status());
  }

  if (doc.contains("corners")) {
    const Json& jk = doc["corners"];
    SCULPT_RETURN_IF_ERROR(NeedArray(jk, "model.corners"));
    for (size_t i = 0; i < jk.size(); ++i) {
      const std::string f = "model.corners[" + std::to_string(i) + "]";
      if (!jk[i].is_object() || !jk[i].contains("coefficient") ||
          !jk[i]["coefficient"].is_number_integer()) {
        return InvalidArgument(f + ".coefficient is missing or not an integer");
      }
      const int64_t q = jk[i]["coefficient"].get<int64_t>();
      if (q < 0 || q >= static_cast<int64_t>(model.coefficient_count())) {
        return Outside(f + ".coefficient", std::to_string(q),
                       std::string("[0, ") +
                           std::to_string(static_cast<long long>(model.coefficient_count()) - 1) +
                           "]");
      }
      CornerFlags flags;
      for (const char* key : {"geometry_c1", "material_c1"}) {
        if (jk[i].contains(key) && !jk[i][key].is_boolean()) {
          return InvalidArgument(f + "." + key + " is not a boolean");
        }
      }
      flags.geometry_c1 = jk[i].contains("geometry_c1") && jk[i]["geometry_c1"].get<bool>();
      flags.material_c1 = jk[i].contains("material_c1") && jk[i]["material_c1"].get<bool>();
      model.set_corner_flags(static_cast<uint32_t>(q), flags);
    }
  }
  return model;
}

Status SaveModel(const CompositeModel& model, const std::string& path, const std::string& name,
                 const std::string& description) {
  std::ofstream out(path);
  if (!out) return NotFound("cannot write " + path);
  out << ModelToJson(model, name, description) << "\n";
  if (!out) return DataLoss("write failed: " + path);
  return Status::Ok();
}

StatusOr<CompositeModel> LoadModel(const std::string& path, size_t max_cells) {
  std::ifstream in(path);
  if (!in) return NotFound("cannot read " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ModelFromJson(ss.str(), max_cells);
}

}  // namespace sculpt::hetero
