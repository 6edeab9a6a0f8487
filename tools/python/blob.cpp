// kiln.open: a mapped blob, its structures with the statistics `kiln dump` prints, and its
// geometry arrays as read-only numpy views of the mapped bytes.
#include <string>

#include "kiln/runtime/error.hpp"
#include "kiln/runtime/structure_registry.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

/// The Python Blob. close() drops its reference to the mapping; structures and arrays taken
/// from it hold their own, so the file stays mapped until the last of them is gone.
class PyBlob {
 public:
  explicit PyBlob(const std::string& path) : path_(path) {
    py::gil_scoped_release release;  // opening validates (and inflates) sections
    handle_ = std::make_shared<const BlobHandle>(Blob::open_file(path));
  }
  const BlobRef& ref() const {
    if (!handle_) throw py::value_error("blob " + path_ + " is closed");
    return handle_;
  }
  const Blob& blob() const { return ref()->blob; }
  const std::string& path() const { return path_; }
  bool closed() const { return !handle_; }
  void close() { handle_.reset(); }

 private:
  std::string path_;
  BlobRef handle_;
};

py::object desc_value(const DescValue& value) {
  return std::visit([](const auto& v) -> py::object { return py::cast(v); }, value);
}

// name, kind, sections and `stats`: the description's fields, then its tables as lists of dicts.
py::dict structure_dict(const Blob& blob, const StructureInfo& info) {
  const Description d = find_structure_kind(info.kind)->describe(blob, info);
  py::dict stats;
  for (const auto& [key, value] : d.fields) stats[py::str(key)] = desc_value(value);
  for (const DescTable& table : d.tables) {
    py::list rows;
    for (const auto& row : table.rows) {
      py::dict r;
      for (std::size_t c = 0; c < row.size() && c < table.columns.size(); ++c)
        r[py::str(table.columns[c])] = desc_value(row[c]);
      rows.append(r);
    }
    stats[py::str(table.key)] = rows;
  }
  py::dict s;
  s["name"] = info.name;
  s["kind"] = info.kind;
  s["sections"] = info.sections;
  s["stats"] = stats;
  return s;
}

py::dict input_dict(const Blob& blob) {
  const InputInfo& in = blob.input();
  py::dict d;
  d["kind"] = std::string(input_kind_name(in.kind));
  d["vertex_count"] = in.vertex_count;
  d["triangle_count"] = in.triangle_count;
  d["feature_count"] = in.feature_count;
  d["closed"] = in.closed;
  d["has_normals"] = in.has_normals;
  d["bounds"] = py::make_tuple(in.bounds.min.x, in.bounds.min.y, in.bounds.min.z, in.bounds.max.x,
                               in.bounds.max.y, in.bounds.max.z);
  return d;
}

template <class T>
py::array view_of(const PyBlob& b, std::span<const T> span, py::ssize_t columns,
                  const py::dtype& dtype) {
  // `span` counts elements of T; a T of `columns` scalars is one row.
  const py::ssize_t rows = py::ssize_t(span.size());
  if (columns == 0) return readonly_view(b.ref(), dtype, {rows}, span.data());
  return readonly_view(b.ref(), dtype, {rows, columns}, span.data());
}

template <class T>
py::dtype dtype_of() {
  return py::dtype::of<T>();
}

void bind_geometry(py::class_<PyBlob>& blob) {
  blob.def_property_readonly(
          "vertices",
          [](const PyBlob& b) { return view_of(b, b.blob().positions(), 3, dtype_of<float>()); },
          "Vertices (a point set's points), float32 (n, 3): a read-only view of the mapped "
          "file.")
      .def_property_readonly(
          "normals",
          [](const PyBlob& b) { return view_of(b, b.blob().normals(), 3, dtype_of<float>()); },
          "Per-vertex normals, float32 (n, 3), empty when the scene has none (read-only view).")
      .def_property_readonly(
          "triangles",
          [](const PyBlob& b) {
            return view_of(b, b.blob().triangles(), 3, dtype_of<std::uint32_t>());
          },
          "Triangles as vertex indices, uint32 (m, 3) (read-only view).")
      .def_property_readonly(
          "triangle_mesh_ids",
          [](const PyBlob& b) {
            return view_of(b, b.blob().triangle_mesh_ids(), 0, dtype_of<std::uint32_t>());
          },
          "Each triangle's mesh, uint32 (m,) (read-only view).");
}

// The 2D inputs' arrays: None when the blob holds another input kind.
void bind_layers(py::class_<PyBlob>& blob) {
  const auto layer = [](const PyBlob& b) -> std::optional<PolygonLayerView> {
    if (b.blob().input().kind != InputKind::kPolygons2) return std::nullopt;
    return b.blob().polygon_layer();
  };
  const auto table = [](const PyBlob& b) -> std::optional<PointTableView> {
    if (b.blob().input().kind != InputKind::kPoint2) return std::nullopt;
    return b.blob().point_table();
  };
  const auto f64 = dtype_of<double>();
  const auto u64 = dtype_of<std::uint64_t>();
  blob.def_property_readonly(
          "layer_vertices",
          [=](const PyBlob& b) -> py::object {
            const auto l = layer(b);
            return l ? py::object(view_of(b, l->vertices, 2, f64)) : py::none();
          },
          "A polygon layer's ring vertices, float64 (n, 2) lon/lat (read-only view); None for "
          "another input.")
      .def_property_readonly(
          "ring_offsets",
          [=](const PyBlob& b) -> py::object {
            const auto l = layer(b);
            return l ? py::object(view_of(b, l->ring_vertices, 0, u64)) : py::none();
          },
          "Ring r owns layer_vertices[ring_offsets[r]:ring_offsets[r+1]] (uint64, read-only).")
      .def_property_readonly(
          "polygon_offsets",
          [=](const PyBlob& b) -> py::object {
            const auto l = layer(b);
            return l ? py::object(view_of(b, l->polygon_rings, 0, u64)) : py::none();
          },
          "Polygon p owns rings polygon_offsets[p]:[p+1], the first the outer ring (uint64).")
      .def_property_readonly(
          "feature_offsets",
          [=](const PyBlob& b) -> py::object {
            const auto l = layer(b);
            return l ? py::object(view_of(b, l->feature_polygons, 0, u64)) : py::none();
          },
          "Feature f owns polygons feature_offsets[f]:[f+1] (uint64, read-only).")
      .def_property_readonly(
          "table_points",
          [=](const PyBlob& b) -> py::object {
            const auto t = table(b);
            return t ? py::object(view_of(b, t->points, 2, f64)) : py::none();
          },
          "A point table's points, float64 (n, 2) (read-only view); None for another input.");
}

Structure open_named(const PyBlob& b, const std::string& name) {
  const Blob& blob = b.blob();
  const StructureInfo* info = blob.structure(name);
  if (info == nullptr) {
    std::string names;
    for (const StructureInfo& s : blob.structures()) names += (names.empty() ? "" : ", ") + s.name;
    throw py::key_error("no structure '" + name + "' in " + b.path() + " (it holds " + names + ")");
  }
  Structure s{b.ref(), info->name, info->kind, nullptr};
  py::gil_scoped_release release;  // the view walks its arrays once
  s.view = open_structure(blob, name);
  return s;
}

}  // namespace

void bind_blob(py::module_& m, py::class_<Structure>& structure) {
  py::class_<PyBlob> blob(m, "Blob", R"(A .kiln blob mapped read-only (kiln.open).

Lifetime: close() (or leaving a `with` block) drops the Blob's own reference to the mapping.
Structures and arrays taken from it hold theirs, so the file stays mapped, and they stay
valid, until the last of them is garbage-collected; the Blob itself then refuses further use.)");
  blob.def(py::init([](const py::object& path) { return PyBlob(path_of(path, "path")); }),
           py::arg("path"))
      .def_property_readonly("path", &PyBlob::path)
      .def_property_readonly("closed", &PyBlob::closed)
      .def("close", &PyBlob::close, "Drops this object's reference to the mapping.")
      .def("__enter__", [](PyBlob& b) -> PyBlob& { return b; })
      .def("__exit__", [](PyBlob& b, py::args) { b.close(); })
      .def_property_readonly(
          "structures",
          [](const PyBlob& b) {
            py::list list;
            for (const StructureInfo& info : b.blob().structures())
              list.append(structure_dict(b.blob(), info));
            return list;
          },
          "One dict per structure: name, kind, sections and stats (what `kiln dump --json` "
          "prints under the kind).")
      .def_property_readonly(
          "input", [](const PyBlob& b) { return input_dict(b.blob()); },
          "What the blob was built from: kind, counts, bounds.")
      .def(
          "verify",
          [](const PyBlob& b) {
            const BlobRef blob = b.ref();  // held: another thread may close() meanwhile
            py::gil_scoped_release release;
            blob->blob.verify();
          },
          "The deep check of `kiln verify`; raises kiln.FormatError on the first problem.")
      .def("__getitem__", &open_named, py::arg("name"),
           "The structure named `name`, opened and validated (KeyError when there is none).")
      .def("__contains__",
           [](const PyBlob& b, const std::string& name) {
             return b.blob().structure(name) != nullptr;
           })
      .def("__len__", [](const PyBlob& b) { return b.blob().structures().size(); })
      .def("__iter__",
           [](const PyBlob& b) {
             py::list names;
             for (const StructureInfo& s : b.blob().structures()) names.append(s.name);
             return py::iter(names);
           })
      .def("__repr__", [](const PyBlob& b) {
        return "<kiln.Blob " + b.path() + (b.closed() ? " (closed)>" : ">");
      });
  bind_geometry(blob);
  bind_layers(blob);
  m.def(
      "open", [](const py::object& path) { return PyBlob(path_of(path, "path")); }, py::arg("path"),
      "Maps the blob at `path` and validates it (kiln.FormatError with the CLI's one-line "
      "reason when it is broken). Use it as a context manager or call close().");

  structure.def_readonly("name", &Structure::name)
      .def_readonly("kind", &Structure::kind)
      .def_property_readonly("capabilities", &Structure::offers,
                             "What the structure answers, as text.")
      .def("__repr__", [](const Structure& s) {
        return "<kiln.Structure '" + s.name + "' (" + s.kind + "): " + s.offers() + ">";
      });
}

}  // namespace kiln::python
