/// @brief External faces, their closed triangle mesh, and material volumes by quadrature.
#include "sculpt/hetero/boundary.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>

#include "sculpt/core/check.h"

namespace sculpt::hetero {
namespace {

using Key = std::array<int64_t, 3>;

Key Quantise(const Vec3& p, double q) {
  return {static_cast<int64_t>(std::llround(p.x / q)), static_cast<int64_t>(std::llround(p.y / q)),
          static_cast<int64_t>(std::llround(p.z / q))};
}

double Quantum(const CompositeModel& model) {
  return 1e-9 * std::max(1.0, model.Bounds().Diagonal());
}

std::vector<Key> FaceKey(const CompositeModel& model, const Face& f, double q) {
  std::vector<Key> key;
  for (int j = 0; j < 4; ++j)
    for (int k = 0; k < 4; ++k) {
      key.push_back(Quantise(
          model.position(model.cell(f.cell).coef[static_cast<size_t>(FaceIndex(f.axis, f.side * 3, j, k))]), q));
    }
  std::sort(key.begin(), key.end());
  return key;
}

// Parameters of point (s, t) on a face: the face's free axes in order.
Vec3 FaceParam(const Face& f, double s, double t) {
  double uvw[3];
  uvw[f.axis] = f.side;
  const int free0 = f.axis == 0 ? 1 : 0, free1 = f.axis == 2 ? 1 : 2;
  uvw[free0] = s;
  uvw[free1] = t;
  return {uvw[0], uvw[1], uvw[2]};
}

}  // namespace

std::vector<Face> ExternalFaces(const CompositeModel& model) {
  const double q = Quantum(model) * 100;
  std::map<std::vector<Key>, int> count;
  std::vector<std::pair<Face, std::vector<Key>>> faces;
  for (int c = 0; c < static_cast<int>(model.cell_count()); ++c)
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side) {
        const Face f{c, axis, side};
        auto key = FaceKey(model, f, q);
        ++count[key];
        faces.emplace_back(f, std::move(key));
      }
  std::vector<Face> out;
  for (const auto& [f, key] : faces) {
    if (count[key] == 1) out.push_back(f);
  }
  return out;
}

double BoundaryMesh::Volume() const {
  double v = 0;
  for (const auto& t : triangles) {
    v += vertices[t[0]].Dot(vertices[t[1]].Cross(vertices[t[2]]));
  }
  return v / 6.0;
}

StatusOr<BoundaryMesh> ExternalBoundaryMesh(const CompositeModel& model, int n) {
  SCULPT_RETURN_IF_ERROR(CheckRange("boundary.subdivisions", n, 1, 64));
  BoundaryMesh mesh;
  const double q = Quantum(model) * 1000;  // welds evaluations of one edge from two cells
  std::map<Key, uint32_t> index;
  auto vertex = [&](const Vec3& p) {
    const Key k = Quantise(p, q);
    auto [it, fresh] = index.emplace(k, static_cast<uint32_t>(mesh.vertices.size()));
    if (fresh) mesh.vertices.push_back(p);
    return it->second;
  };
  for (const Face& f : ExternalFaces(model)) {
    const Hyperpatch h = model.CellPatch(f.cell);
    // Outward: along +axis on side 1 and −axis on side 0, measured by the cell's own tangent.
    const Vec3 mid = FaceParam(f, 0.5, 0.5);
    const auto d = h.Derivatives(mid.x, mid.y, mid.z);
    const int free0 = f.axis == 0 ? 1 : 0, free1 = f.axis == 2 ? 1 : 2;
    const Vec3 normal = d[static_cast<size_t>(free0)].Cross(d[static_cast<size_t>(free1)]);
    const Vec3 out = d[static_cast<size_t>(f.axis)] * (f.side ? 1.0 : -1.0);
    const bool flip = normal.Dot(out) < 0;
    std::vector<uint32_t> grid(static_cast<size_t>((n + 1) * (n + 1)));
    for (int a = 0; a <= n; ++a)
      for (int b = 0; b <= n; ++b) {
        const Vec3 uvw = FaceParam(f, static_cast<double>(a) / n, static_cast<double>(b) / n);
        grid[static_cast<size_t>(a * (n + 1) + b)] = vertex(h.Evaluate(uvw.x, uvw.y, uvw.z));
      }
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b) {
        const uint32_t v00 = grid[static_cast<size_t>(a * (n + 1) + b)];
        const uint32_t v10 = grid[static_cast<size_t>((a + 1) * (n + 1) + b)];
        const uint32_t v01 = grid[static_cast<size_t>(a * (n + 1) + b + 1)];
        const uint32_t v11 = grid[static_cast<size_t>((a + 1) * (n + 1) + b + 1)];
        std::array<uint32_t, 3> t1{v00, v10, v11}, t2{v00, v11, v01};
        if (flip) {
          std::swap(t1[1], t1[2]);
          std::swap(t2[1], t2[2]);
        }
        // Collapsed cells (a wedge at an axis) give degenerate triangles: skip them.
        for (const auto& t : {t1, t2}) {
          if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) mesh.triangles.push_back(t);
        }
      }
  }
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (const auto& t : mesh.triangles)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = t[static_cast<size_t>(e)], b = t[static_cast<size_t>((e + 1) % 3)];
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  for (const auto& [e, c] : edges) mesh.open_edges += c != 2;
  return mesh;
}

Status WriteObj(const BoundaryMesh& mesh, const std::string& path) {
  std::ofstream out(path);
  if (!out) return NotFound("cannot write " + path);
  out.precision(17);
  for (const Vec3& v : mesh.vertices) out << "v " << v.x << ' ' << v.y << ' ' << v.z << '\n';
  for (const auto& t : mesh.triangles) {
    out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  }
  if (!out) return DataLoss("write failed: " + path);
  return Status::Ok();
}

MaterialVolumes IntegrateVolumes(const CompositeModel& model) {
  // 6-point Gauss–Legendre on [0, 1]: det J has degree 8 per axis, A·det J degree 11.
  static const double x[6] = {0.033765242898423975, 0.16939530676686776, 0.38069040695840156,
                              0.61930959304159844,  0.83060469323313224, 0.96623475710157603};
  static const double w[6] = {0.085662246189585178, 0.18038078652406931, 0.23395696728634552,
                              0.23395696728634552,  0.18038078652406931, 0.085662246189585178};
  MaterialVolumes v;
  v.per_material.assign(static_cast<size_t>(model.materials()), 0.0);
  std::vector<double> a(static_cast<size_t>(model.materials()));
  for (int c = 0; c < static_cast<int>(model.cell_count()); ++c) {
    const Hyperpatch h = model.CellPatch(c);
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        for (int k = 0; k < 6; ++k) {
          const double dv = w[i] * w[j] * w[k] * std::abs(h.JacobianDeterminant(x[i], x[j], x[k]));
          h.Materials(x[i], x[j], x[k], a);
          v.total += dv;
          for (size_t m = 0; m < a.size(); ++m) v.per_material[m] += a[m] * dv;
        }
  }
  return v;
}

}  // namespace sculpt::hetero
