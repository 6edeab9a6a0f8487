// 2D queries from Python: point in polygon (locate), polygons meeting boxes, points in boxes
// (range), and the features' ids and names.
#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include "kiln/runtime/parallel.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

template <class T>
using Rows = py::array_t<T, py::array::c_style | py::array::forcecast>;

py::object locate(const Structure& s, py::handle lon, py::handle lat,
                  const py::object& threads_arg) {
  const PolygonQueries& q = s.need(&StructureView::polygons, "locate");
  const unsigned threads = thread_count(threads_arg);
  const bool scalar = !py::isinstance<py::array>(lon) && !py::isinstance<py::sequence>(lon) &&
                      !py::isinstance<py::array>(lat) && !py::isinstance<py::sequence>(lat);
  const auto x = vector_of<double>(lon, "lon");
  const auto y = vector_of<double>(lat, "lat");
  if (x.shape(0) != y.shape(0))
    throw py::value_error("lat: expected shape (" + std::to_string(x.shape(0)) +
                          ",) to match lon, got (" + std::to_string(y.shape(0)) + ",)");
  py::array_t<std::int64_t> out(x.shape(0));
  std::int64_t* o = out.mutable_data();
  const double *xs = x.data(), *ys = y.data();
  {
    py::gil_scoped_release release;
    // The capability's batch call (the one `kiln query --op polygon` makes), a slice of at
    // most kSlice points at a time so that the interleaved copy stays small; a non-finite
    // coordinate is in no polygon.
    constexpr std::size_t kSlice = std::size_t(1) << 20;
    const std::size_t n = std::size_t(x.shape(0));
    std::vector<format::Double2> points(std::min(n, kSlice));
    std::vector<std::uint32_t> found(points.size());
    for (std::size_t at = 0; at < n; at += kSlice) {
      const std::size_t m = std::min(kSlice, n - at);
      for (std::size_t i = 0; i < m; ++i) {
        const double px = xs[at + i], py = ys[at + i];
        points[i] = std::isfinite(px) && std::isfinite(py) ? format::Double2{px, py}
                                                           : format::Double2{NAN, NAN};
      }
      q.locate_many(std::span(points).first(m), std::span(found).first(m), threads);
      for (std::size_t i = 0; i < m; ++i)
        o[at + i] = found[i] == PolygonQueries::kNone ? -1 : std::int64_t(found[i]);
    }
  }
  if (scalar) return py::int_(o[0]);
  return out;
}

/// (box_index, item) pairs for every box, in box order, each box's items as `find` lists them.
template <class Find>
py::tuple box_pairs(py::handle boxes, const py::object& threads_arg, Find find) {
  const unsigned threads = thread_count(threads_arg);
  const Rows<double> in = rows_of<double>(boxes, "boxes", 4);
  const std::size_t m = std::size_t(in.shape(0));
  std::vector<std::vector<std::uint32_t>> found(m);
  const double* b = in.data();
  {
    py::gil_scoped_release release;
    parallel_for_batched(m, 256, threads, [&](std::size_t i) {
      const double* v = b + 4 * i;
      // A NaN bound selects nothing: no comparison with it holds.
      if (std::isnan(v[0]) || std::isnan(v[1]) || std::isnan(v[2]) || std::isnan(v[3])) return;
      find(format::Box2d{{v[0], v[1]}, {v[2], v[3]}}, found[i]);
    });
  }
  std::size_t total = 0;
  for (const auto& f : found) total += f.size();
  py::array_t<std::int64_t> box{py::ssize_t(total)}, item{py::ssize_t(total)};
  std::int64_t *bp = box.mutable_data(), *ip = item.mutable_data();
  for (std::size_t i = 0, k = 0; i < m; ++i)
    for (const auto id : found[i]) bp[k] = std::int64_t(i), ip[k++] = id;
  return py::make_tuple(box, item);
}

py::tuple attributes(const Structure& s, py::handle indices) {
  const Blob& blob = s.blob->blob;
  StringTableView ids, names;
  std::size_t count = 0;
  if (blob.input().kind == InputKind::kPolygons2) {
    const auto layer = blob.polygon_layer();
    ids = layer.ids, names = layer.names, count = layer.feature_count();
  } else if (blob.input().kind == InputKind::kPoint2) {
    const auto table = blob.point_table();
    ids = table.ids, names = table.names, count = table.feature_count();
  } else {
    throw py::type_error("structure '" + s.name + "' (" + s.kind +
                         ") is not over a 2D layer: attributes() needs features");
  }
  const auto idx = vector_of<std::int64_t>(indices, "indices");
  py::list id_list, name_list;
  for (py::ssize_t k = 0; k < idx.shape(0); ++k) {
    const std::int64_t i = idx.data()[k];
    if (i < -1 || i >= std::int64_t(count))
      throw py::value_error("indices: " + std::to_string(i) + " is out of range for " +
                            std::to_string(count) + " features (-1 = none)");
    const auto text = [&](const StringTableView& t) -> py::object {
      if (i < 0 || t.empty()) return py::none();
      return py::str(std::string(t[std::size_t(i)]));
    };
    id_list.append(text(ids));
    name_list.append(text(names));
  }
  return py::make_tuple(id_list, name_list);
}

}  // namespace

void bind_polygons(py::class_<Structure>& structure) {
  structure
      .def("locate", &locate, py::arg("lon"), py::arg("lat"), py::arg("threads") = py::none(),
           R"(Point in polygon: the feature index containing each (lon, lat) point, int64 (m,),
-1 where none does; the lowest index where features overlap (half-open boundary rule of
docs/FORMAT.md). lon and lat are numbers or (m,) arrays, converted to float64; two numbers
give an int. A NaN or infinite coordinate gives -1. Releases the GIL.)")
      .def(
          "features_in_box",
          [](const Structure& s, py::handle boxes, const py::object& threads) {
            const PolygonQueries& q = s.need(&StructureView::polygons, "features_in_box");
            return box_pairs(boxes, threads,
                             [&](const format::Box2d& b, auto& out) { q.features_in_box(b, out); });
          },
          py::arg("boxes"), py::arg("threads") = py::none(),
          "Every feature meeting each closed box (min_x, min_y, max_x, max_y), float64 "
          "(m, 4): (box_index, feature_index) int64 arrays, by box then feature.")
      .def(
          "range",
          [](const Structure& s, py::handle boxes, const py::object& threads) {
            const Point2Queries& q = s.need(&StructureView::points2, "range");
            return box_pairs(boxes, threads,
                             [&](const format::Box2d& b, auto& out) { q.range(b, out); });
          },
          py::arg("boxes"), py::arg("threads") = py::none(),
          "Every point of a 2D point table inside each closed box (min_x, min_y, max_x, "
          "max_y), float64 (m, 4): (box_index, point_index) int64 arrays, by box then point "
          "index (indices into blob.table_points). A box with a NaN bound selects nothing.")
      .def("attributes", &attributes, py::arg("indices"),
           "The features' ids and names: two lists of str (None for index -1 or a missing "
           "column), for a structure over a polygon layer or a point table.");
}

}  // namespace kiln::python
