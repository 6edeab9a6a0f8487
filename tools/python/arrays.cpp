// Numpy arrays in and out: read-only views of a blob's bytes, and argument conversion with
// errors that name the argument and the shape it needs.
#include <cmath>
#include <string>

#include "kiln/runtime/parallel.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

std::string shape_text(const py::array& a) {
  std::string text = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) text += (d ? ", " : "") + std::to_string(a.shape(d));
  return text + (a.ndim() == 1 ? ",)" : ")");
}

template <class T>
const char* dtype_name() {
  if constexpr (std::is_same_v<T, float>) return "float32";
  if constexpr (std::is_same_v<T, double>) return "float64";
  if constexpr (std::is_same_v<T, std::int64_t>) return "int64";
  return "numbers";
}

// The array, converted; a TypeError naming `arg` when it holds no numbers.
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> convert(py::handle value, const char* arg,
                                                                  const std::string& expected) {
  using Array = py::array_t<T, py::array::c_style | py::array::forcecast>;
  if (value.is_none() || py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value))
    throw py::type_error(std::string(arg) + ": expected " + expected + " of numbers, got " +
                         std::string(py::str(value.get_type().attr("__name__"))));
  Array a = Array::ensure(value);
  if (!a)
    throw py::type_error(std::string(arg) + ": expected " + expected + " convertible to " +
                         dtype_name<T>() + ", got " +
                         std::string(py::str(value.get_type().attr("__name__"))));
  return a;
}

}  // namespace

py::array readonly_view(const BlobRef& blob, const py::dtype& dtype, std::vector<py::ssize_t> shape,
                        const void* data) {
  // The capsule owns a reference to the blob: numpy keeps it as the array's base, so the
  // mapping outlives the Blob object, close() and every Structure, until the last view dies.
  auto* owner = new BlobRef(blob);
  py::capsule base(owner, [](void* p) { delete static_cast<BlobRef*>(p); });
  static const std::byte empty[16]{};  // numpy wants a pointer even for zero elements
  py::array a(dtype, std::move(shape), data != nullptr ? data : empty, base);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> rows_of(py::handle value, const char* arg,
                                                                  py::ssize_t columns,
                                                                  bool* single) {
  const std::string expected = "an array of shape (n, " + std::to_string(columns) + ")";
  auto a = convert<T>(value, arg, expected);
  if (single != nullptr) *single = false;
  if (a.ndim() == 1 && a.shape(0) == columns && single != nullptr) {
    *single = true;
    return a.reshape({py::ssize_t{1}, columns});
  }
  if (a.ndim() != 2 || a.shape(1) != columns)
    throw py::value_error(std::string(arg) + ": expected shape (n, " + std::to_string(columns) +
                          ")" + (single ? " or (" + std::to_string(columns) + ",)" : "") +
                          ", got " + shape_text(a));
  return a;
}

template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> vector_of(py::handle value,
                                                                    const char* arg) {
  auto a = convert<T>(value, arg, "a number or an array of shape (n,)");
  if (a.ndim() == 0) return a.reshape({py::ssize_t{1}});
  if (a.ndim() != 1)
    throw py::value_error(std::string(arg) + ": expected shape (n,), got " + shape_text(a));
  return a;
}

template py::array_t<float, py::array::c_style | py::array::forcecast> rows_of<float>(py::handle,
                                                                                      const char*,
                                                                                      py::ssize_t,
                                                                                      bool*);
template py::array_t<double, py::array::c_style | py::array::forcecast> rows_of<double>(py::handle,
                                                                                        const char*,
                                                                                        py::ssize_t,
                                                                                        bool*);
template py::array_t<float, py::array::c_style | py::array::forcecast> vector_of<float>(
    py::handle, const char*);
template py::array_t<double, py::array::c_style | py::array::forcecast> vector_of<double>(
    py::handle, const char*);
template py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>
vector_of<std::int64_t>(py::handle, const char*);

std::string path_of(py::handle value, const char* arg) {
  if (!py::isinstance<py::str>(value) && !py::hasattr(value, "__fspath__"))
    throw py::type_error(std::string(arg) + ": expected a path (str or os.PathLike), got " +
                         std::string(py::str(value.get_type().attr("__name__"))));
  return py::str(py::module_::import("os").attr("fspath")(value));
}

unsigned thread_count(const py::object& threads) {
  if (threads.is_none()) return thread_count(py::int_(0));
  if (!py::isinstance<py::int_>(threads) || py::isinstance<py::bool_>(threads))
    throw py::type_error("threads: expected None or an int, got " +
                         std::string(py::str(threads.get_type().attr("__name__"))));
  const long long n = threads.cast<long long>();
  if (n < -1 || n > 4096)
    throw py::value_error("threads: expected None, -1 or 0 (every core), or 1..4096, got " +
                          std::to_string(n));
  // "Every core" resolved once: hardware_concurrency() reads /sys on every call, which cost
  // a small batch ~70 us per parallel_for.
  static const unsigned all = resolve_thread_count(0);
  return n <= 0 ? all : unsigned(n);
}

void need_non_negative(double value, const char* arg) {
  if (!(value >= 0))
    throw py::value_error(std::string(arg) + ": expected a number >= 0, got " +
                          std::to_string(value));
}

std::string Structure::offers() const {
  std::string list;
  const auto add = [&](bool has, const char* what) {
    if (has) list += (list.empty() ? "" : ", ") + std::string(what);
  };
  add(view->rays(), "rays (intersect, occluded)");
  add(view->surface(), "surface (closest, inside)");
  add(view->neighbors() || view->points2(), "neighbours (knn, radius)");
  add(view->occupancy(), "occupancy (occupied)");
  add(view->polygons(), "polygons (locate)");
  add(view->points2(), "2D range (range)");
  add(view->events(), "events (count, series, tiles, topk)");
  return list.empty() ? "nothing" : list;
}

void Structure::throw_missing(std::string_view op) const {
  throw py::type_error("structure '" + name + "' (" + kind + ") cannot answer " + std::string(op) +
                       "; it offers " + offers());
}

}  // namespace kiln::python
