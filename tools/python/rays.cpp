// Ray queries from Python: batches of origins and directions traced through a structure's rays
// capability (the same trace_records `kiln trace` runs), with the GIL released.
#include <cmath>
#include <cstring>
#include <limits>

#include "kiln/runtime/parallel.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

constexpr std::size_t kBatch = 4096;
using FloatRows = py::array_t<float, py::array::c_style | py::array::forcecast>;

/// A row of intersect's structured array for triangle structures: numpy's aligned layout of
/// [t f4, prim i8, u f4, v f4].
struct HitRow {
  float t;
  std::int64_t prim;
  float u, v;
};
static_assert(sizeof(HitRow) == 24 && offsetof(HitRow, prim) == 8 && offsetof(HitRow, v) == 20);

/// Voxel structures add the voxel (finest grid, -1 on a miss), the attached normal (zero when
/// the blob stores none) and the entered face's normal.
struct VoxelHitRow {
  HitRow hit;
  std::int64_t voxel[3];
  float normal[3];
  float face_normal[3];
};
static_assert(sizeof(VoxelHitRow) == 72 && offsetof(VoxelHitRow, normal) == 48);

/// A voxel structure that stores colours adds the hit voxel's RGBA8 colour.
struct VoxelColorRow {
  VoxelHitRow voxel;
  std::uint8_t color[4];
};
static_assert(sizeof(VoxelColorRow) == 80 && offsetof(VoxelColorRow, color) == 72);

/// kind 0: triangles; 1: voxels; 2: voxels with colours.
py::dtype make_hit_dtype(int kind) {
  const bool voxel = kind > 0;
  py::list fields;
  fields.append(py::make_tuple("t", "<f4"));
  fields.append(py::make_tuple("prim", "<i8"));
  fields.append(py::make_tuple("u", "<f4"));
  fields.append(py::make_tuple("v", "<f4"));
  if (voxel) {
    fields.append(py::make_tuple("voxel", "<i8", py::make_tuple(3)));
    fields.append(py::make_tuple("normal", "<f4", py::make_tuple(3)));
    fields.append(py::make_tuple("face_normal", "<f4", py::make_tuple(3)));
  }
  if (kind == 2) fields.append(py::make_tuple("color", "u1", py::make_tuple(4)));
  return py::dtype::from_args(
      py::module_::import("numpy").attr("dtype")(fields, py::arg("align") = true));
}

/// The result dtypes, made once (a small batch would otherwise spend more on them than on its
/// rays). Leaked on purpose: a static py::object would be released after the interpreter.
const py::dtype& hit_dtype(int kind) {
  static const py::dtype* const dtypes[3] = {new py::dtype(make_hit_dtype(0)),
                                             new py::dtype(make_hit_dtype(1)),
                                             new py::dtype(make_hit_dtype(2))};
  return *dtypes[kind];
}

/// A batch of rays read from Python: origins and directions (n, 3) or one (3,) row broadcast,
/// tmin and tmax scalars or (n,).
struct RayBatch {
  FloatRows org, dir;
  py::array_t<float, py::array::c_style | py::array::forcecast> tmin, tmax;
  std::size_t count = 0;

  RayBatch(py::handle origins, py::handle directions, py::handle t0, py::handle t1) {
    bool one_org = false, one_dir = false;
    org = rows_of<float>(origins, "origins", 3, &one_org);
    dir = rows_of<float>(directions, "directions", 3, &one_dir);
    tmin = vector_of<float>(t0, "tmin");
    tmax = vector_of<float>(t1, "tmax");
    count = std::size_t(std::max(org.shape(0), dir.shape(0)));
    const auto fits = [&](py::ssize_t n, bool broadcast) {
      return std::size_t(n) == count || (broadcast && n == 1);
    };
    if (!fits(org.shape(0), one_org))
      throw py::value_error("origins: expected shape (" + std::to_string(count) +
                            ", 3) or (3,) to match directions, got (" +
                            std::to_string(org.shape(0)) + ", 3)");
    if (!fits(dir.shape(0), one_dir))
      throw py::value_error("directions: expected shape (" + std::to_string(count) +
                            ", 3) or (3,) to match origins, got (" + std::to_string(dir.shape(0)) +
                            ", 3)");
    for (const auto& [a, name] : {std::pair{&tmin, "tmin"}, std::pair{&tmax, "tmax"}})
      if (!fits(a->shape(0), true))
        throw py::value_error(std::string(name) + ": expected a number or shape (" +
                              std::to_string(count) + ",), got (" + std::to_string(a->shape(0)) +
                              ",)");
  }

  /// Ray i; nullopt when a coordinate is not finite or a bound is NaN (answered as a miss).
  std::optional<Ray> ray(std::size_t i, const float* o, const float* d, const float* lo,
                         const float* hi) const {
    const float* oi = o + 3 * (org.shape(0) == 1 ? 0 : i);
    const float* di = d + 3 * (dir.shape(0) == 1 ? 0 : i);
    const float t0 = lo[tmin.shape(0) == 1 ? 0 : i], t1 = hi[tmax.shape(0) == 1 ? 0 : i];
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(oi[k]) || !std::isfinite(di[k])) return std::nullopt;
    if (std::isnan(t0) || std::isnan(t1)) return std::nullopt;
    return Ray{{oi[0], oi[1], oi[2]}, t0, {di[0], di[1], di[2]}, t1};
  }
};

/// Traces the batch in tasks of kBatch rays, each task on one thread: its rays built, traced
/// through trace_records (the path of `kiln trace`, so the records are the CLI's) and handed
/// to `out(i, record)` while still in cache: one pass, no batch-sized temporaries. A ray with
/// a non-finite coordinate is not traced: its record is a miss. GIL released by the caller.
template <class Out>
void trace(const RayQueries& q, const RayBatch& b, bool any_hit, unsigned threads, Out out) {
  const std::size_t size = q.record_size();
  const float *o = b.org.data(), *d = b.dir.data(), *lo = b.tmin.data(), *hi = b.tmax.data();
  const float inf = std::numeric_limits<float>::infinity();
  parallel_for((b.count + kBatch - 1) / kBatch, threads, [&](std::size_t task) {
    const std::size_t first = task * kBatch, n = std::min(kBatch, b.count - first);
    std::vector<Ray> rays(n);
    std::vector<std::uint8_t> valid(n);
    std::vector<std::byte> records(n * size);
    for (std::size_t k = 0; k < n; ++k) {
      const auto ray = b.ray(first + k, o, d, lo, hi);
      valid[k] = ray.has_value();
      // A harmless empty interval stands in for an invalid ray; its record is replaced below.
      rays[k] = ray ? *ray : Ray{{0, 0, 0}, 0, {1, 0, 0}, 0};
    }
    q.trace_records(rays, records, any_hit, 1);
    for (std::size_t k = 0; k < n; ++k) {
      std::byte* record = records.data() + k * size;
      if (!valid[k]) {
        std::memset(record, 0, size);
        std::memcpy(record, &inf, sizeof inf);
        if (size == sizeof(VoxelHitRecord))
          std::memset(record + 4, 0xFF, 12);  // no voxel
        else
          std::memset(record + 4, 0xFF, 4);  // no primitive
      }
      out(first + k, record);
    }
  });
}

std::int64_t id_or_minus_one(std::uint32_t id) {
  return id == kNoHit ? -1 : std::int64_t(id);
}

HitRow row_of(const Hit& h) {
  return {h.t, id_or_minus_one(h.prim), h.u, h.v};
}

VoxelHitRow row_of(const VoxelHitRecord& r) {
  VoxelHitRow row;
  row.hit = {r.t, std::isinf(r.t) ? -1 : 0, 0, 0};
  row.voxel[0] = id_or_minus_one(r.x), row.voxel[1] = id_or_minus_one(r.y);
  row.voxel[2] = id_or_minus_one(r.z);
  std::memcpy(row.normal, r.normal, sizeof row.normal);
  std::memcpy(row.face_normal, r.face_normal, sizeof row.face_normal);
  return row;
}

/// Records of type Record into rows of intersect's structured array.
template <class Record, class Row>
void trace_rows(const RayQueries& q, const RayBatch& b, unsigned threads, Row* rows) {
  trace(q, b, false, threads, [&](std::size_t i, const std::byte* record) {
    Record r;
    std::memcpy(&r, record, sizeof r);
    rows[i] = row_of(r);
  });
}

/// Rows with colours: each valid ray cast by closest_voxel (the same cast trace_records runs,
/// plus the colour lookup); an invalid ray is a miss.
void color_rows(const RayQueries& q, const RayBatch& b, unsigned threads, VoxelColorRow* rows) {
  const float *o = b.org.data(), *d = b.dir.data(), *lo = b.tmin.data(), *hi = b.tmax.data();
  parallel_for((b.count + kBatch - 1) / kBatch, threads, [&](std::size_t task) {
    for (std::size_t i = task * kBatch; i < std::min(b.count, (task + 1) * kBatch); ++i) {
      VoxelHit h;  // a miss
      if (const auto ray = b.ray(i, o, d, lo, hi)) q.closest_voxel(*ray, h);
      rows[i].voxel = row_of(to_record(h));
      std::memcpy(rows[i].color, &h.color, sizeof rows[i].color);  // r in the low byte
    }
  });
}

py::array intersect(const Structure& s, py::handle origins, py::handle directions, py::handle tmin,
                    py::handle tmax, const py::object& threads_arg) {
  const RayQueries& q = s.need(&StructureView::rays, "intersect");
  const unsigned threads = thread_count(threads_arg);
  const RayBatch batch(origins, directions, tmin, tmax);
  const bool voxel = q.record_size() == sizeof(VoxelHitRecord);
  const bool colors = voxel && q.has_colors();
  py::array out(hit_dtype(int(voxel) + int(colors)),
                std::vector<py::ssize_t>{py::ssize_t(batch.count)});
  void* data = out.mutable_data();
  {
    py::gil_scoped_release release;
    if (colors)
      color_rows(q, batch, threads, static_cast<VoxelColorRow*>(data));
    else if (voxel)
      trace_rows<VoxelHitRecord>(q, batch, threads, static_cast<VoxelHitRow*>(data));
    else
      trace_rows<Hit>(q, batch, threads, static_cast<HitRow*>(data));
  }
  return out;
}

py::array_t<bool> occluded(const Structure& s, py::handle origins, py::handle directions,
                           py::handle tmin, py::handle tmax, const py::object& threads_arg) {
  const RayQueries& q = s.need(&StructureView::rays, "occluded");
  const unsigned threads = thread_count(threads_arg);
  const RayBatch batch(origins, directions, tmin, tmax);
  py::array_t<bool> out(py::ssize_t(batch.count));
  bool* data = out.mutable_data();
  {
    py::gil_scoped_release release;
    // Every record starts with t, +inf on a miss.
    trace(q, batch, true, threads, [&](std::size_t i, const std::byte* record) {
      float t;
      std::memcpy(&t, record, sizeof t);
      data[i] = !std::isinf(t);
    });
  }
  return out;
}

}  // namespace

void bind_rays(py::class_<Structure>& structure) {
  const float inf = std::numeric_limits<float>::infinity();
  structure
      .def("intersect", &intersect, py::arg("origins"), py::arg("directions"),
           py::arg("tmin") = 0.0f, py::arg("tmax") = inf, py::arg("threads") = py::none(),
           R"(Closest hit of each ray: a structured array with t (float32, inf on a miss), prim
(int64, -1 on a miss), u, v (float32 barycentrics); voxel structures add voxel (int64 x 3),
normal and face_normal (float32 x 3), and color (uint8 x 4, RGBA) when the structure stores
colours. origins and directions are (n, 3) (or one (3,) row for
all), converted to float32; tmin and tmax are numbers or (n,). A ray with a NaN or infinite
coordinate, or a NaN bound, is a miss. Releases the GIL; threads=None uses every core.)")
      .def("occluded", &occluded, py::arg("origins"), py::arg("directions"), py::arg("tmin") = 0.0f,
           py::arg("tmax") = inf, py::arg("threads") = py::none(),
           "Whether each ray hits anything in [tmin, tmax] (any hit): bool (n,). Same inputs "
           "as intersect.");
}

}  // namespace kiln::python
