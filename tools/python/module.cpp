// The extension module kiln._kiln: one class per concept (Blob, Structure), the queries bound
// per capability in their own files, kiln.build, and kiln.FormatError for broken blobs.
#include "kiln/runtime/error.hpp"
#include "kiln_python.hpp"

PYBIND11_MODULE(_kiln, m) {
  namespace kp = kiln::python;
  m.doc() = "Kiln blobs from Python: open, query (rays, neighbours, surfaces, 2D, events), build.";
  // A broken blob: the one line `kiln verify` and `kiln dump` print after their prefix.
  static kp::py::exception<kiln::BlobError> format_error(m, "FormatError", PyExc_ValueError);
  kp::py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const kiln::BlobError& e) {
      PyErr_SetString(format_error.ptr(), e.what());
    }
  });
  kp::py::class_<kp::Structure> structure(
      m, "Structure",
      "A structure of a blob (blob[name]): its queries are those of its capabilities; a query "
      "it cannot answer raises TypeError saying what it offers. Holds the blob's mapping.");
  kp::bind_blob(m, structure);
  kp::bind_rays(structure);
  kp::bind_points(structure);
  kp::bind_polygons(structure);
  kp::bind_events(structure);
  kp::bind_build(m);
}
