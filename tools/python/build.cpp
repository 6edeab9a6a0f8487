// kiln.build: the compiler in process, with `kiln build`'s options (the structure kinds' global
// flags come from the compiler's registry as keyword arguments) and its error lines.
#include <filesystem>
#include <map>

#include "kiln/compiler/advise.hpp"
#include "kiln/compiler/build_job.hpp"
#include "kiln/compiler/geo_import.hpp"
#include "kiln/compiler/structure_builder.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

/// A global structure flag as a keyword: "--bvh-width" -> "bvh_width".
std::string keyword_of(const std::string& flag) {
  std::string key = flag.substr(flag.find_first_not_of('-'));
  for (char& c : key)
    if (c == '-') c = '_';
  return key;
}

bool truthy(py::handle value) {
  return py::reinterpret_borrow<py::object>(value).cast<bool>();
}

/// The global flags given as keywords (flag -> value text, "true" for a switch set), as
/// `kiln build` passes them to resolve_structure_request; other keywords are a TypeError.
std::map<std::string, std::string> structure_flags(const py::kwargs& kwargs) {
  std::map<std::string, const StructureOption*> by_keyword;
  for (const StructureBuilder* builder : structure_builders())
    for (const StructureOption& option : builder->options)
      if (!option.flag.empty()) by_keyword.emplace(keyword_of(option.flag), &option);
  std::map<std::string, std::string> flags;
  for (const auto& [key, value] : kwargs) {
    const std::string k = py::str(key);
    const auto it = by_keyword.find(k);
    if (it == by_keyword.end()) {
      std::string known;
      for (const auto& [name, option] : by_keyword) known += (known.empty() ? "" : ", ") + name;
      throw py::type_error("build() got an unexpected keyword argument '" + k +
                           "'; structure options: " + known);
    }
    if (it->second->is_switch) {
      if (truthy(value)) flags[it->second->flag] = "true";
    } else {
      flags[it->second->flag] = py::isinstance<py::bool_>(value)
                                    ? std::string(truthy(value) ? "true" : "false")
                                    : std::string(py::str(value));
    }
  }
  return flags;
}

std::vector<std::string> strings_of(const py::object& value, const char* arg) {
  if (value.is_none()) return {};
  if (py::isinstance<py::str>(value) || py::hasattr(value, "__fspath__"))
    return {path_of(value, arg)};
  if (!py::isinstance<py::sequence>(value) && !py::hasattr(value, "__iter__"))
    throw py::type_error(std::string(arg) + ": expected a str or a list of str");
  std::vector<std::string> out;
  for (const auto item : value) out.push_back(path_of(item, arg));
  return out;
}

/// `kiln build`'s check that an output does not name an input (exit 2 there).
void refuse_clash(const std::vector<std::string>& inputs, const std::string& output) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const auto& input : inputs)
    if (fs::exists(output, ec) && fs::equivalent(input, output, ec))
      throw py::value_error("output " + output + " is also an input");
}

/// The geo and event options, checked as `kiln build` checks them.
void read_layer_options(BuildOptions& options, const py::dict& o) {
  const auto text = [&](const char* key) {
    return o.contains(key) && !o[key].is_none() ? py::str(o[key]).cast<std::string>()
                                                : std::string();
  };
  if (o.contains("name_property")) options.geo.name_property = text("name_property");
  options.geo.x_column = text("x_column");
  options.geo.y_column = text("y_column");
  options.geo.skip_invalid = o.contains("skip_invalid") && py::bool_(o["skip_invalid"]);
  resolve_point_columns(options.geo, text("lon_column"), text("lat_column"), options.inputs);
  options.events.lat = text("lat"), options.events.lon = text("lon");
  options.events.time = text("time");
  for (const auto& c : strings_of(o.contains("category") ? o["category"] : py::none(), "category"))
    options.events.categories.push_back(parse_event_category(c));
  options.events.skip_invalid = options.geo.skip_invalid;
}

py::dict report_of(const BuildJobReport& job) {
  py::dict r;
  r["cache_hit"] = job.cache_hit;
  r["cache_key"] = job.cache_key;
  r["warnings"] = job.warnings;
  py::list structures;
  for (const AccelReport& a : job.accels) {
    py::dict s;
    s["name"] = a.name, s["kind"] = a.kind, s["summary"] = a.summary;
    s["build_seconds"] = a.build_seconds;
    structures.append(s);
  }
  r["structures"] = structures;
  return r;
}

py::dict build(const py::object& inputs, const py::object& out, const py::object& accel,
               bool compress, int level, const py::object& threads, const py::object& depfile,
               const py::object& cache_dir, const py::object& progress, const py::dict& layer,
               const py::kwargs& kwargs) {
  BuildJob job;
  job.options.inputs = strings_of(inputs, "inputs");
  if (job.options.inputs.empty()) throw py::value_error("inputs: expected at least one file");
  job.output = strings_of(out, "out").at(0);
  job.depfile = depfile.is_none() ? "" : strings_of(depfile, "depfile").at(0);
  job.cache_dir = cache_dir.is_none() ? "" : strings_of(cache_dir, "cache_dir").at(0);
  if (level < 1 || level > 22) throw py::value_error("compression_level: expected 1..22");
  job.options.compression = {compress, level};
  job.options.threads = thread_count(threads);
  const auto flags = structure_flags(kwargs);
  for (const auto& spec : strings_of(accel, "accel"))
    job.options.structures.push_back(is_auto_spec(spec) ? resolve_auto_request(spec)
                                                        : resolve_structure_request(spec, flags));
  read_layer_options(job.options, layer);
  refuse_clash(job.options.inputs, job.output);
  BuildProgress report;
  if (!progress.is_none())
    report = [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
      py::gil_scoped_acquire acquire;  // called on this thread; a raise aborts the build
      progress(std::string(stage), done, total);
    };
  BuildJobReport result;
  {
    py::gil_scoped_release release;
    result = run_build_job(job, report);
  }
  return report_of(result);
}

}  // namespace

void bind_build(py::module_& m) {
  static py::exception<ImportError> build_error(m, "BuildError", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const ImportError& e) {
      PyErr_SetString(build_error.ptr(), e.what());
    }
  });
  m.def(
      "build",
      [](const py::object& inputs, const py::object& out, const py::object& accel, bool compress,
         int level, const py::object& threads, const py::object& depfile,
         const py::object& cache_dir, const py::object& progress, const py::object& name_property,
         const py::object& lon_column, const py::object& lat_column, const py::object& x_column,
         const py::object& y_column, bool skip_invalid, const py::object& lat,
         const py::object& lon, const py::object& time, const py::object& category,
         const py::kwargs& kwargs) {
        py::dict layer;
        layer["name_property"] = name_property, layer["lon_column"] = lon_column;
        layer["lat_column"] = lat_column, layer["x_column"] = x_column;
        layer["y_column"] = y_column, layer["skip_invalid"] = skip_invalid;
        layer["lat"] = lat, layer["lon"] = lon, layer["time"] = time;
        layer["category"] = category;
        return build(inputs, out, accel, compress, level, threads, depfile, cache_dir, progress,
                     layer, kwargs);
      },
      py::arg("inputs"), py::arg("out"), py::arg("accel") = py::none(), py::kw_only(),
      py::arg("compress") = false, py::arg("compression_level") = 9,
      py::arg("threads") = py::none(), py::arg("depfile") = py::none(),
      py::arg("cache_dir") = py::none(), py::arg("progress") = py::none(),
      py::arg("name_property") = "name", py::arg("lon_column") = py::none(),
      py::arg("lat_column") = py::none(), py::arg("x_column") = py::none(),
      py::arg("y_column") = py::none(), py::arg("skip_invalid") = false,
      py::arg("lat") = py::none(), py::arg("lon") = py::none(), py::arg("time") = py::none(),
      py::arg("category") = py::none(),
      R"(Runs `kiln build` in process: imports `inputs` (a path or a list), compiles the
structures of `accel` ("bvh", "points:leaf-size=4", ... or a list; "auto") and writes `out`
atomically. Keywords are kiln build's flags with '_' for '-': compress, compression_level,
threads, depfile, cache_dir, name_property, lon_column/lat_column (x_column/y_column),
skip_invalid, lat/lon/time/category (event tables), and every structure kind's global flag
(bvh_max_leaf=4, bvh_width=8, time_bin="1h", ...). progress(stage, done, total) is called as
the build advances (on the calling thread; raising aborts the build). Returns a report dict.
Bad options raise ValueError, unknown keywords TypeError, failed imports kiln.BuildError, with
kiln build's message.)");
}

}  // namespace kiln::python
