// Aggregate event queries from Python (the nanocube's events capability): count, series,
// tiles and topk with the fields of `kiln query`'s JSON lines.
#include "kiln/compiler/event_table.hpp"
#include "kiln/runtime/nanocube.hpp"
#include "kiln_python.hpp"

namespace kiln::python {

namespace {

/// A time given as Unix seconds (int), ISO 8601 text, or anything numpy.datetime64 takes.
std::int64_t seconds_of(py::handle value) {
  if (py::isinstance<py::int_>(value)) return value.cast<std::int64_t>();
  if (py::isinstance<py::str>(value)) {
    if (const auto t = parse_event_time(value.cast<std::string>())) return *t;
    throw py::value_error("time: '" + value.cast<std::string>() +
                          "' is not an ISO 8601 time or Unix seconds");
  }
  const auto np = py::module_::import("numpy");
  try {
    return np.attr("datetime64")(value, "s").attr("astype")("int64").cast<std::int64_t>();
  } catch (const py::error_already_set&) {
    throw py::type_error("time: expected Unix seconds, ISO 8601 text or a datetime, got " +
                         std::string(py::str(value.get_type().attr("__name__"))));
  }
}

EventSelection selection_of(const py::object& box, const py::object& tile, const py::object& time,
                            const py::object& where) {
  EventSelection s;
  if (!box.is_none()) {
    const auto b = vector_of<double>(box, "box");
    if (b.shape(0) != 4)
      throw py::value_error("box: expected (min_lon, min_lat, max_lon, max_lat)");
    s.box = format::Box2d{{b.at(0), b.at(1)}, {b.at(2), b.at(3)}};
  }
  if (!tile.is_none()) {
    const auto t = vector_of<std::int64_t>(tile, "tile");
    if (t.shape(0) != 3 || t.at(0) < 0 || t.at(1) < 0 || t.at(2) < 0 || t.at(0) > 32 ||
        t.at(1) > 0xFFFFFFFFll || t.at(2) > 0xFFFFFFFFll)
      throw py::value_error("tile: expected (z, x, y), non-negative");
    s.tile = std::array<std::uint32_t, 3>{std::uint32_t(t.at(0)), std::uint32_t(t.at(1)),
                                          std::uint32_t(t.at(2))};
  }
  if (!time.is_none()) {
    if (!py::isinstance<py::sequence>(time) || py::isinstance<py::str>(time) || py::len(time) != 2)
      throw py::value_error("time: expected (start, end)");
    const auto t = time.cast<py::sequence>();
    s.time = std::array<std::int64_t, 2>{seconds_of(t[0]), seconds_of(t[1])};
  }
  if (!where.is_none()) {
    if (!py::isinstance<py::dict>(where))
      throw py::type_error("where: expected a dict of category -> label or labels");
    for (const auto& [name, labels] : where.cast<py::dict>())
      s.where.emplace_back(py::str(name).cast<std::string>(),
                           py::isinstance<py::str>(labels)
                               ? std::vector<std::string>{labels.cast<std::string>()}
                               : labels.cast<std::vector<std::string>>());
  }
  return s;
}

py::object datetime(std::int64_t seconds) {
  return py::module_::import("numpy").attr("datetime64")(seconds, "s");
}

/// The snapped box (when a box or tile was given) and interval (when a time was), as the JSON
/// lines give them.
void add_snap(py::dict& answer, const EventQueries& cube, const EventSelection& s) {
  const EventSnap snap = cube.snap(s);
  if (s.box || s.tile)
    answer["box"] = py::make_tuple(snap.box.min.x, snap.box.min.y, snap.box.max.x, snap.box.max.y);
  if (s.time) answer["time"] = py::make_tuple(datetime(snap.t0), datetime(snap.t1));
}

py::array structured(const std::vector<std::pair<const char*, const char*>>& fields,
                     std::size_t rows) {
  py::list list;
  for (const auto& [name, type] : fields) list.append(py::make_tuple(name, type));
  return py::array(py::dtype::from_args(py::module_::import("numpy").attr("dtype")(list)),
                   std::vector<py::ssize_t>{py::ssize_t(rows)});
}

// Every query: the capability, the selection, the answer under the op's key, then the snap.
template <class Answer>
py::dict run(const Structure& s, const char* op, const py::object& box, const py::object& tile,
             const py::object& time, const py::object& where, Answer answer) {
  const EventQueries& cube = s.need(&StructureView::events, op);
  const EventSelection selection = selection_of(box, tile, time, where);
  py::dict out;
  answer(cube, selection, out);
  add_snap(out, cube, selection);
  return out;
}

#define KILN_SELECTION                                                      \
  py::kw_only(), py::arg("box") = py::none(), py::arg("tile") = py::none(), \
                 py::arg("time") = py::none(), py::arg("where") = py::none()

}  // namespace

void bind_events(py::class_<Structure>& structure) {
  using O = const py::object&;
  structure
      .def(
          "count",
          [](const Structure& s, O box, O tile, O time, O where) {
            return run(s, "count", box, tile, time, where, [](auto& cube, auto& sel, auto& out) {
              std::uint64_t n = 0;
              {
                py::gil_scoped_release release;
                n = cube.count(sel);
              }
              out["count"] = n;
            });
          },
          KILN_SELECTION,
          R"(Events in the selection: {"count": int, "box": snapped box, "time": snapped
interval}, the fields of `kiln query --op count` (box and time only when given). box is
(min_lon, min_lat, max_lon, max_lat); tile (z, x, y); time (start, end) as Unix seconds, ISO
8601 text or datetimes; where {category: label or [labels]}. Bad requests raise ValueError.)")
      .def(
          "series",
          [](const Structure& s, O bin, O box, O tile, O time, O where) {
            const std::int64_t width = py::isinstance<py::int_>(bin)
                                           ? bin.cast<std::int64_t>()
                                           : parse_duration(py::str(bin).cast<std::string>());
            return run(s, "series", box, tile, time, where, [&](auto& cube, auto& sel, auto& out) {
              std::vector<std::pair<std::int64_t, std::uint64_t>> bins;
              {
                py::gil_scoped_release release;
                bins = cube.series(sel, width);
              }
              py::array a = structured({{"time", "<M8[s]"}, {"count", "<u8"}}, bins.size());
              auto* p = static_cast<std::int64_t*>(a.mutable_data());
              for (std::size_t i = 0; i < bins.size(); ++i)
                p[2 * i] = bins[i].first, p[2 * i + 1] = std::int64_t(bins[i].second);
              out["series"] = a;
            });
          },
          py::arg("bin") = "1d", KILN_SELECTION,
          "Counts per time bin (seconds or \"1h\", \"1d\", ...): {\"series\": structured array "
          "(time datetime64[s], count uint64), every bin listed}, plus the snap.")
      .def(
          "tiles",
          [](const Structure& s, std::uint32_t zoom, O box, O tile, O time, O where) {
            return run(s, "tiles", box, tile, time, where, [&](auto& cube, auto& sel, auto& out) {
              std::vector<EventTileCount> tiles;
              {
                py::gil_scoped_release release;
                tiles = cube.tiles(sel, zoom);
              }
              py::array a = structured({{"z", "<u4"}, {"x", "<u4"}, {"y", "<u4"}, {"count", "<u8"}},
                                       tiles.size());
              auto* p = static_cast<std::byte*>(a.mutable_data());
              for (std::size_t i = 0; i < tiles.size(); ++i) {
                const std::uint32_t zxy[3] = {tiles[i].z, tiles[i].x, tiles[i].y};
                std::memcpy(p + 20 * i, zxy, 12);
                std::memcpy(p + 20 * i + 12, &tiles[i].count, 8);
              }
              out["tiles"] = a;
            });
          },
          py::arg("zoom"), KILN_SELECTION,
          "Counts per Web-Mercator tile at `zoom`: {\"tiles\": structured array (z, x, y, "
          "count)} of the tiles with events, sorted by x, y, plus the snap.")
      .def(
          "topk",
          [](const Structure& s, std::size_t k, const std::string& by, O box, O tile, O time,
             O where) {
            return run(s, "topk", box, tile, time, where, [&](auto& cube, auto& sel, auto& out) {
              std::vector<EventLabelCount> top;
              {
                py::gil_scoped_release release;
                top = cube.topk(sel, by, k);
              }
              py::list list;
              for (const auto& l : top) list.append(py::make_tuple(l.label, l.count));
              out["topk"] = list;
            });
          },
          py::arg("k"), py::arg("by"), KILN_SELECTION,
          "The k labels of category `by` with most events: {\"topk\": [(label, count), ...]}, "
          "ties by label, plus the snap.");
}

}  // namespace kiln::python
