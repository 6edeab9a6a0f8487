// The Python module `kiln` (issue 23): what its files share. The module sits on the runtime's
// registry and capability interfaces only; it never names a structure kind.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/capabilities.hpp"

namespace kiln::python {

namespace py = pybind11;

/// The opened blob, shared by the Python Blob, every Structure opened from it and every array
/// view of its bytes: the mapping stays until the last of them is gone.
struct BlobHandle {
  explicit BlobHandle(Blob b) : blob(std::move(b)) {}
  Blob blob;
};
using BlobRef = std::shared_ptr<const BlobHandle>;

/// A structure of a blob, opened through the runtime's registry. Holds its blob.
struct Structure {
  BlobRef blob;
  std::string name, kind;
  std::unique_ptr<StructureView> view;

  /// The capability `get`, or a TypeError naming the structure, `op` and what it offers.
  template <class Capability>
  const Capability& need(const Capability* (StructureView::*get)() const,
                         std::string_view op) const {
    const Capability* c = ((*view).*get)();
    if (c == nullptr) throw_missing(op);
    return *c;
  }
  /// The capabilities it has: "rays, surface".
  std::string offers() const;
  [[noreturn]] void throw_missing(std::string_view op) const;
};

/// A read-only numpy array over `data` (bytes owned by the blob), keeping the blob alive.
py::array readonly_view(const BlobRef& blob, const py::dtype& dtype, std::vector<py::ssize_t> shape,
                        const void* data);

/// `value` as a C-contiguous array of `T` with `columns` per row: shape (n, columns), or
/// (columns,) as one row (`single` set). Converts dtype and order (a copy only when needed);
/// otherwise ValueError/TypeError naming `arg` and the expected shape.
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> rows_of(py::handle value, const char* arg,
                                                                  py::ssize_t columns,
                                                                  bool* single = nullptr);

/// `value` as a C-contiguous 1-D array of `T` (a scalar is one element).
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> vector_of(py::handle value,
                                                                    const char* arg);

/// A path argument: str or os.PathLike (TypeError naming `arg` otherwise).
std::string path_of(py::handle value, const char* arg);

/// A `threads=` argument (None, 0 or -1: every core) as a resolved thread count.
unsigned thread_count(const py::object& threads);

/// Raises ValueError naming `arg` unless `value` >= 0 and not NaN.
void need_non_negative(double value, const char* arg);

void bind_blob(py::module_& m, py::class_<Structure>& structure);
void bind_rays(py::class_<Structure>& structure);
void bind_points(py::class_<Structure>& structure);
void bind_polygons(py::class_<Structure>& structure);
void bind_events(py::class_<Structure>& structure);
void bind_build(py::module_& m);

}  // namespace kiln::python
