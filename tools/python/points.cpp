// Point queries from Python: k nearest and radius (3D point sets and 2D point tables), closest
// point and inside (surfaces), occupied (voxels). Shapes and dtypes of knn follow
// scipy.spatial.cKDTree.query.
#include <cmath>
#include <limits>

#include "kiln/runtime/parallel.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

constexpr std::size_t kBatch = 1024;

template <class T>
using Rows = py::array_t<T, py::array::c_style | py::array::forcecast>;

bool finite(const float* p, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(p[k])) return false;
  return true;
}
bool finite(const double* p, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(p[k])) return false;
  return true;
}

/// Runs body(i, scratch) for every query in batches of kBatch, each batch with its own scratch.
template <class Scratch, class Body>
void for_each_query(std::size_t count, unsigned threads, Scratch prototype, Body body) {
  parallel_for((count + kBatch - 1) / kBatch, threads, [&](std::size_t b) {
    Scratch scratch = prototype;
    for (std::size_t i = b * kBatch; i < std::min(count, (b + 1) * kBatch); ++i) body(i, scratch);
  });
}

/// The ranks knn returns (1-based, as cKDTree's k: an int k means 1..k) and whether the answer
/// drops the rank axis (k == 1 as an int).
struct Ranks {
  std::vector<std::size_t> ranks;
  std::size_t max = 0;
  bool squeeze = false;
};

Ranks ranks_of(const py::object& k) {
  Ranks r;
  const auto need = [](long long v) {
    if (v < 1 || v > (1 << 20))
      throw py::value_error("k: expected an int >= 1 (or a list of them), got " +
                            std::to_string(v));
    return std::size_t(v);
  };
  if (py::isinstance<py::int_>(k) && !py::isinstance<py::bool_>(k)) {
    r.max = need(k.cast<long long>());
    for (std::size_t i = 1; i <= r.max; ++i) r.ranks.push_back(i);
    r.squeeze = r.max == 1;
    return r;
  }
  if (!py::isinstance<py::sequence>(k) || py::isinstance<py::str>(k))
    throw py::type_error("k: expected an int or a list of ints, got " +
                         std::string(py::str(k.get_type().attr("__name__"))));
  for (const auto item : k.cast<py::sequence>()) {
    if (!py::isinstance<py::int_>(item)) throw py::type_error("k: expected a list of ints");
    r.ranks.push_back(need(item.cast<long long>()));
    r.max = std::max(r.max, r.ranks.back());
  }
  if (r.ranks.empty()) throw py::value_error("k: expected a non-empty list");
  return r;
}

/// Distances and indices (m, ranks) as cKDTree.query gives them: float64 and int64, inf and
/// `n` where there are fewer than k points.
struct KnnOut {
  py::array_t<double> d;
  py::array_t<std::int64_t> i;
  double* dp;
  std::int64_t* ip;
  KnnOut(std::size_t m, std::size_t cols)
      : d({py::ssize_t(m), py::ssize_t(cols)}), i({py::ssize_t(m), py::ssize_t(cols)}) {
    dp = d.mutable_data();
    ip = i.mutable_data();
  }
};

// 3D: the capability sorts by float squared distance, (dx*dx + dy*dy) + dz*dz, then index;
// the distance returned is recomputed in float64 from the stored float32 point, as cKDTree
// computes it from float32 data.
void knn3(const NeighborQueries& q, std::span<const format::Float3> pts, const float* in,
          const Ranks& k, KnnOut& out, std::size_t m, unsigned threads) {
  const std::size_t cols = k.ranks.size();
  for_each_query(m, threads, std::vector<Neighbor>(k.max), [&](std::size_t i, auto& found) {
    const float* p = in + 3 * i;
    const std::size_t got = finite(p, 3) ? q.nearest({p[0], p[1], p[2]}, found) : 0;
    for (std::size_t c = 0; c < cols; ++c) {
      const std::size_t r = k.ranks[c] - 1;
      double dist = std::numeric_limits<double>::infinity();
      std::int64_t id = std::int64_t(pts.size());
      if (r < got) {
        id = found[r].id;
        const format::Float3& x = pts[id];
        const double dx = double(x.x) - p[0], dy = double(x.y) - p[1], dz = double(x.z) - p[2];
        dist = std::sqrt(dx * dx + dy * dy + dz * dz);
      }
      out.dp[i * cols + c] = dist;
      out.ip[i * cols + c] = id;
    }
  });
}

void knn2(const Point2Queries& q, std::size_t n, const double* in, const Ranks& k, KnnOut& out,
          std::size_t m, unsigned threads) {
  const std::size_t cols = k.ranks.size();
  for_each_query(m, threads, std::vector<Neighbor2>(k.max), [&](std::size_t i, auto& found) {
    const double* p = in + 2 * i;
    const std::size_t got = finite(p, 2) ? q.nearest({p[0], p[1]}, found) : 0;
    for (std::size_t c = 0; c < cols; ++c) {
      const std::size_t r = k.ranks[c] - 1;
      out.dp[i * cols + c] =
          r < got ? std::sqrt(found[r].distance_squared) : std::numeric_limits<double>::infinity();
      out.ip[i * cols + c] = r < got ? std::int64_t(found[r].index) : std::int64_t(n);
    }
  });
}

py::object knn(const Structure& s, py::handle points, const py::object& k_arg,
               const py::object& threads_arg) {
  const Ranks k = ranks_of(k_arg);
  const unsigned threads = thread_count(threads_arg);
  bool single = false;
  std::optional<KnnOut> out;
  if (const NeighborQueries* q = s.view->neighbors()) {
    const Rows<float> in = rows_of<float>(points, "points", 3, &single);
    const std::size_t m = std::size_t(in.shape(0));
    out.emplace(m, k.ranks.size());
    const auto pts = s.blob->blob.positions();
    py::gil_scoped_release release;
    knn3(*q, pts, in.data(), k, *out, m, threads);
  } else if (const Point2Queries* q = s.view->points2()) {
    const Rows<double> in = rows_of<double>(points, "points", 2, &single);
    const std::size_t m = std::size_t(in.shape(0));
    out.emplace(m, k.ranks.size());
    const std::size_t n = s.blob->blob.point_table().points.size();
    py::gil_scoped_release release;
    knn2(*q, n, in.data(), k, *out, m, threads);
  } else {
    s.throw_missing("knn");
  }
  if (single && k.squeeze) return py::make_tuple(out->dp[0], out->ip[0]);
  if (single) return py::make_tuple(out->d.attr("reshape")(-1), out->i.attr("reshape")(-1));
  if (k.squeeze) return py::make_tuple(out->d.attr("reshape")(-1), out->i.attr("reshape")(-1));
  return py::make_tuple(out->d, out->i);
}

/// One index array per query, by (distance, index).
py::object radius(const Structure& s, py::handle points, double r, const py::object& threads_arg) {
  need_non_negative(r, "r");
  const unsigned threads = thread_count(threads_arg);
  bool single = false;
  std::vector<std::vector<std::int64_t>> found;
  if (const NeighborQueries* q = s.view->neighbors()) {
    const Rows<float> in = rows_of<float>(points, "points", 3, &single);
    found.resize(std::size_t(in.shape(0)));
    const float* p = in.data();
    py::gil_scoped_release release;
    for_each_query(found.size(), threads, std::vector<Neighbor>{}, [&](std::size_t i, auto& near) {
      const float* x = p + 3 * i;
      if (!finite(x, 3)) return;
      q->within_radius({x[0], x[1], x[2]}, float(r), near);
      for (const Neighbor& n : near) found[i].push_back(n.id);
    });
  } else if (const Point2Queries* q = s.view->points2()) {
    const Rows<double> in = rows_of<double>(points, "points", 2, &single);
    found.resize(std::size_t(in.shape(0)));
    const double* p = in.data();
    py::gil_scoped_release release;
    for_each_query(found.size(), threads, std::vector<Neighbor2>{}, [&](std::size_t i, auto& near) {
      const double* x = p + 2 * i;
      if (!finite(x, 2)) return;
      q->within_radius({x[0], x[1]}, r, near);
      for (const Neighbor2& n : near) found[i].push_back(n.index);
    });
  } else {
    s.throw_missing("radius");
  }
  py::list out;
  for (const auto& ids : found) out.append(py::array_t<std::int64_t>(ids.size(), ids.data()));
  if (single) return out[0];
  return out;
}

py::object closest(const Structure& s, py::handle points, float max_distance,
                   const py::object& threads_arg) {
  const SurfaceQueries& q = s.need(&StructureView::surface, "closest");
  if (std::isnan(max_distance) || max_distance <= 0)
    throw py::value_error("max_distance: expected a number > 0");
  const unsigned threads = thread_count(threads_arg);
  bool single = false;
  const Rows<float> in = rows_of<float>(points, "points", 3, &single);
  const auto m = in.shape(0);
  py::array_t<float> dist(m), at({m, py::ssize_t(3)});
  py::array_t<std::int64_t> prim(m);
  float *dp = dist.mutable_data(), *ap = at.mutable_data();
  std::int64_t* pp = prim.mutable_data();
  const float* p = in.data();
  {
    py::gil_scoped_release release;
    for_each_query(std::size_t(m), threads, 0, [&](std::size_t i, int) {
      const float* x = p + 3 * i;
      ClosestPoint c;
      c.point = {NAN, NAN, NAN};
      if (finite(x, 3)) c = q.closest_point({x[0], x[1], x[2]}, max_distance);
      if (c.prim == kNoHit) c.point = {NAN, NAN, NAN};
      dp[i] = c.distance;
      pp[i] = c.prim == kNoHit ? -1 : std::int64_t(c.prim);
      ap[3 * i] = c.point.x, ap[3 * i + 1] = c.point.y, ap[3 * i + 2] = c.point.z;
    });
  }
  if (single) return py::make_tuple(dp[0], at.attr("reshape")(3), pp[0]);
  return py::make_tuple(dist, at, prim);
}

/// inside (surface) or occupied (voxels): a bool per point, False for a non-finite point.
template <class Test>
py::object per_point_bool(py::handle points, const py::object& threads_arg, Test test) {
  const unsigned threads = thread_count(threads_arg);
  bool single = false;
  const Rows<float> in = rows_of<float>(points, "points", 3, &single);
  py::array_t<bool> out(in.shape(0));
  bool* o = out.mutable_data();
  const float* p = in.data();
  {
    py::gil_scoped_release release;
    for_each_query(std::size_t(in.shape(0)), threads, 0, [&](std::size_t i, int) {
      const float* x = p + 3 * i;
      o[i] = finite(x, 3) && test(format::Float3{x[0], x[1], x[2]});
    });
  }
  if (single) return py::bool_(o[0]);
  return out;
}

}  // namespace

void bind_points(py::class_<Structure>& structure) {
  structure
      .def("knn", &knn, py::arg("points"), py::arg("k") = 1, py::arg("threads") = py::none(),
           R"(The k nearest points, as scipy.spatial.cKDTree.query answers: (distances float64,
indices int64), shape (m,) for k=1, (m, k) otherwise (k may be a list of 1-based ranks);
a single (3,) point gives a float and an int (k=1) or (k,) arrays. Sorted by distance, ties
by index; where fewer than k points exist, distance inf and index n (the point count).
3D point sets take float32 (m, 3) queries; 2D point tables float64 (m, 2) (indices into
blob.table_points). A NaN or infinite query finds nothing (inf, n).)")
      .def("radius", &radius, py::arg("points"), py::arg("r"), py::arg("threads") = py::none(),
           "Every point within distance r of each query: a list of int64 index arrays sorted "
           "by (distance, index), as `kiln query --op radius`; one array for a single point. "
           "A non-finite query finds nothing.")
      .def("closest", &closest, py::arg("points"),
           py::arg("max_distance") = std::numeric_limits<float>::infinity(),
           py::arg("threads") = py::none(),
           "The closest surface point of each query: (distance float32 (m,), point float32 "
           "(m, 3), prim int64 (m,)); inf, NaN and -1 when nothing lies within max_distance "
           "or the query is not finite.")
      .def(
          "inside",
          [](const Structure& s, py::handle points, const py::object& threads) {
            const SurfaceQueries& q = s.need(&StructureView::surface, "inside");
            return per_point_bool(points, threads,
                                  [&](const format::Float3& p) { return q.inside(p); });
          },
          py::arg("points"), py::arg("threads") = py::none(),
          "Whether each point lies inside the surface (ray parity; meaningful for closed "
          "meshes): bool (m,). A non-finite point is False.")
      .def(
          "occupied",
          [](const Structure& s, py::handle points, const py::object& threads) {
            const OccupancyQueries& q = s.need(&StructureView::occupancy, "occupied");
            return per_point_bool(points, threads,
                                  [&](const format::Float3& p) { return q.occupied(p); });
          },
          py::arg("points"), py::arg("threads") = py::none(),
          "Whether each point lies in a voxel structure's solid: bool (m,).");
}

}  // namespace kiln::python
