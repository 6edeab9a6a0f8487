// `kiln query --op polygon` (point in polygon) and `--op polygons-in-box` over a polygon layer.
// CSV in gives CSV out (the input's columns as read, then the answer's); binary in gives
// binary out. Batches run on every core, each writing its own slot, so the output never
// depends on the thread count.
#include "query_polygon.hpp"

#include <cmath>
#include <cstring>
#include <iostream>
#include <span>
#include <stdexcept>
#include <vector>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/tools/structure_choice.hpp"

namespace kiln::cli {

namespace {

using format::Box2d;
using format::Double2;

constexpr std::size_t kBatch = 4096;
constexpr std::uint32_t kNone = PolygonQueries::kNone;

bool ends_with(std::string_view text, std::string_view tail) {
  return text.size() >= tail.size() && text.substr(text.size() - tail.size()) == tail;
}

bool is_csv(const std::string& path) {
  return ends_with(path, ".csv") || ends_with(path, ".csv.zst");
}

// A field as RFC 4180 needs it: quoted when it holds a comma, quote, CR or LF.
void put_field(std::string& out, std::string_view field) {
  if (field.find_first_of(",\"\r\n") == std::string_view::npos) {
    out += field;
    return;
  }
  out += '"';
  for (const char c : field) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  out += '"';
}

double parse_double(const CsvReader& reader, std::string_view field, std::string_view column) {
  const std::optional<double> value = parse_csv_number(field);
  if (!value)
    throw std::runtime_error(
        reader.where(std::string(column) + " '" + std::string(field) + "' is not a number"));
  return *value;
}

// Runs `answer(i, part)` for every index in parallel batches, concatenated in order.
template <class Part, class Answer>
Part answer_all(std::size_t count, unsigned threads, Answer answer) {
  const std::size_t batches = (count + kBatch - 1) / kBatch;
  std::vector<Part> parts(batches);
  parallel_for(batches, threads, [&](std::size_t b) {
    for (std::size_t i = b * kBatch; i < std::min(count, (b + 1) * kBatch); ++i)
      answer(i, parts[b]);
  });
  Part out;
  for (const auto& part : parts) out.insert(out.end(), part.begin(), part.end());
  return out;
}

template <class T>
void append_pod(std::vector<std::byte>& out, const T& value) {
  const auto* p = reinterpret_cast<const std::byte*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::vector<Double2> points;  // per row (polygon) or unused
};

std::vector<std::string> copy_fields(const std::vector<std::string_view>& fields) {
  return {fields.begin(), fields.end()};
}

CsvTable read_points_csv(const PolygonQueryArgs& args) {
  const InputBytes input = read_input_bytes(args.in);
  CsvReader reader(args.in,
                   {reinterpret_cast<const char*>(input.bytes.data()), input.bytes.size()});
  std::vector<std::string_view> fields;
  CsvTable table;
  if (!reader.next(fields)) throw std::runtime_error(args.in + ": empty CSV (no header row)");
  table.header = copy_fields(fields);
  const auto lon = csv_column(fields, args.lon_column), lat = csv_column(fields, args.lat_column);
  if (!lon || !lat)
    throw std::runtime_error(args.in + ": no column '" + (lon ? args.lat_column : args.lon_column) +
                             "' in the header (--lon-column / --lat-column)");
  while (reader.next(fields)) {
    if (fields.size() <= std::max(*lon, *lat))
      throw std::runtime_error(reader.where("too few fields"));
    table.points.push_back({parse_double(reader, fields[*lon], args.lon_column),
                            parse_double(reader, fields[*lat], args.lat_column)});
    table.rows.push_back(copy_fields(fields));
  }
  return table;
}

// The lowest feature per point, through the capability's batch call on `threads` threads.
std::vector<std::uint32_t> locate_points(const PolygonQueries& q, std::span<const Double2> points,
                                         unsigned threads) {
  std::vector<std::uint32_t> found(points.size());
  q.locate_many(points, found, threads);
  return found;
}

std::string locate_csv(const PolygonQueries& q, const PolygonLayerView& layer,
                       const PolygonQueryArgs& args) {
  const CsvTable t = read_points_csv(args);
  const std::vector<std::uint32_t> found =
      args.all ? std::vector<std::uint32_t>() : locate_points(q, t.points, args.threads);
  std::string head;
  for (const auto& field : t.header) put_field(head, field), head += ',';
  head += "polygon_index,polygon_id,polygon_name\n";
  auto row = [&](std::string& out, std::size_t i, std::uint32_t f) {
    for (const auto& field : t.rows[i]) put_field(out, field), out += ',';
    if (f == kNone) {
      out += "-1,,\n";
      return;
    }
    out += std::to_string(f) + ',';
    put_field(out, layer.ids.empty() ? std::string_view() : layer.ids[f]);
    out += ',';
    put_field(out, layer.names.empty() ? std::string_view() : layer.names[f]);
    out += '\n';
  };
  return head + answer_all<std::string>(t.points.size(), args.threads,
                                        [&](std::size_t i, std::string& out) {
                                          if (!args.all) return row(out, i, found[i]);
                                          std::vector<std::uint32_t> all;
                                          q.locate_all(t.points[i], all);
                                          if (all.empty()) row(out, i, kNone);
                                          for (const auto f : all) row(out, i, f);
                                        });
}

// The binary file as `stride` float64 per query (copied: a file's bytes need not be aligned).
std::vector<double> read_doubles(const std::string& path, std::size_t stride) {
  const InputBytes input = read_input_bytes(path);
  const std::size_t bytes = input.bytes.size();
  if (bytes % (stride * sizeof(double)) != 0)
    throw std::runtime_error(path + ": size " + std::to_string(bytes) + " is not a multiple of " +
                             std::to_string(stride * 8) + " bytes (float64 x " +
                             std::to_string(stride) + " per query)");
  std::vector<double> values(bytes / sizeof(double));
  std::memcpy(values.data(), input.bytes.data(), bytes);
  return values;
}

std::vector<std::byte> locate_binary(const PolygonQueries& q, const PolygonQueryArgs& args) {
  const std::vector<double> v = read_doubles(args.in, 2);
  if (!args.all) {
    std::vector<Double2> points(v.size() / 2);
    for (std::size_t i = 0; i < points.size(); ++i) points[i] = {v[2 * i], v[2 * i + 1]};
    const std::vector<std::uint32_t> found = locate_points(q, points, args.threads);
    std::vector<std::byte> out(found.size() * sizeof(std::uint32_t));
    std::memcpy(out.data(), found.data(), out.size());
    return out;
  }
  return answer_all<std::vector<std::byte>>(v.size() / 2, args.threads,
                                            [&](std::size_t i, std::vector<std::byte>& out) {
                                              const Double2 p{v[2 * i], v[2 * i + 1]};
                                              std::vector<std::uint32_t> all;
                                              q.locate_all(p, all);
                                              append_pod(out, std::uint32_t(all.size()));
                                              for (const auto f : all) append_pod(out, f);
                                            });
}

std::vector<Box2d> read_boxes_csv(const std::string& path) {
  const InputBytes input = read_input_bytes(path);
  CsvReader reader(path, {reinterpret_cast<const char*>(input.bytes.data()), input.bytes.size()});
  std::vector<std::string_view> fields;
  std::vector<Box2d> boxes;
  static const char* names[] = {"min_x", "min_y", "max_x", "max_y"};
  bool first = true;
  while (reader.next(fields)) {
    if (fields.size() < 4)
      throw std::runtime_error(reader.where("expected min_x,min_y,max_x,max_y"));
    if (first && fields[0] == "min_x") {  // an optional header row
      first = false;
      continue;
    }
    first = false;
    double c[4];
    for (int k = 0; k < 4; ++k) c[k] = parse_double(reader, fields[k], names[k]);
    boxes.push_back({{c[0], c[1]}, {c[2], c[3]}});
  }
  return boxes;
}

int run(const PolygonQueryArgs& args) {
  const Blob blob = Blob::open_file(args.blob);
  const ChosenStructure chosen = choose_structure(blob, args.accel, &StructureView::polygons,
                                                  "answer point-in-polygon queries");
  const PolygonQueries& q = *chosen.view->polygons();
  if (args.op == "polygon") {
    if (is_csv(args.in)) {
      const std::string text = locate_csv(q, blob.polygon_layer(), args);
      write_file_atomically(args.out, std::as_bytes(std::span(text.data(), text.size())));
    } else {
      write_file_atomically(args.out, locate_binary(q, args));
    }
    return 0;
  }
  std::vector<Box2d> boxes;
  if (is_csv(args.in)) {
    boxes = read_boxes_csv(args.in);
  } else {
    const std::vector<double> v = read_doubles(args.in, 4);
    for (std::size_t i = 0; i + 3 < v.size(); i += 4)
      boxes.push_back({{v[i], v[i + 1]}, {v[i + 2], v[i + 3]}});
  }
  if (is_csv(args.in)) {
    const std::string text =
        "box_index,feature_index\n" +
        answer_all<std::string>(boxes.size(), args.threads, [&](std::size_t i, std::string& out) {
          std::vector<std::uint32_t> found;
          q.features_in_box(boxes[i], found);
          for (const auto f : found) out += std::to_string(i) + ',' + std::to_string(f) + '\n';
        });
    write_file_atomically(args.out, std::as_bytes(std::span(text.data(), text.size())));
    return 0;
  }
  write_file_atomically(
      args.out, answer_all<std::vector<std::byte>>(
                    boxes.size(), args.threads, [&](std::size_t i, std::vector<std::byte>& out) {
                      std::vector<std::uint32_t> found;
                      q.features_in_box(boxes[i], found);
                      for (const auto f : found)
                        append_pod(out, std::uint32_t(i)), append_pod(out, f);
                    }));
  return 0;
}

}  // namespace

bool is_polygon_op(const std::string& op) {
  return op == "polygon" || op == "polygons-in-box";
}

void add_polygon_query_options(CLI::App* command, PolygonQueryArgs& args) {
  command->add_flag("--all", args.all,
                    "polygon: every containing feature, not the lowest; CSV out: one row per "
                    "(point, feature), a point in none once with -1; binary out: per point a "
                    "uint32 count then the uint32 feature indices");
  command->add_option("--lon-column", args.lon_column, "polygon, CSV in: the x column (longitude)");
  command->add_option("--lat-column", args.lat_column, "polygon, CSV in: the y column (latitude)");
}

int run_polygon_query(const PolygonQueryArgs& args) {
  try {
    return run(args);
  } catch (const std::exception& e) {
    std::cerr << "kiln query: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln::cli
