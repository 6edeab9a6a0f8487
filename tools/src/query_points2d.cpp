// `kiln query --op range|knn2d|radius2d` on a 2D point table. Queries come as CSV rows (a header
// row is optional: a first row whose first field is not a number is one) or as raw float64
// values (4 per box: min_x, min_y, max_x, max_y; 2 per point: x, y); answers are CSV rows
// sorted by query, then as the structure sorts them, with point indices mapped to the table's
// rows (features), so they join back onto the input the table was read from.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "kiln/compiler/csv_reader.hpp"
#include "kiln/compiler/import.hpp"
#include "kiln/runtime/atomic_file.hpp"
#include "kiln/runtime/blob.hpp"
#include "kiln/runtime/parallel.hpp"
#include "kiln/tools/structure_choice.hpp"
#include "query_points2d.hpp"

namespace kiln::cli {

namespace {

constexpr std::size_t kBatch = 1024;

bool parse_double(std::string_view text, double& value) {
  const std::optional<double> number = parse_csv_number(text);
  if (number) value = *number;
  return number && std::isfinite(*number);
}

// `stride` numbers per query, from CSV (by extension .csv, also inside .zst) or raw float64.
std::vector<double> read_queries(const std::string& path, std::size_t stride) {
  const InputBytes input = read_input_bytes(path);
  std::vector<double> values;
  const std::string& name = input.inner_name;
  if (name.size() < 4 || name.compare(name.size() - 4, 4, ".csv") != 0) {
    if (input.bytes.size() % (stride * sizeof(double)) != 0)
      throw std::runtime_error(path + ": size " + std::to_string(input.bytes.size()) +
                               " is not a multiple of " + std::to_string(stride * 8) +
                               " bytes (float64 x " + std::to_string(stride) +
                               " per query), nor a .csv file");
    values.resize(input.bytes.size() / sizeof(double));
    std::memcpy(values.data(), input.bytes.data(), input.bytes.size());
    for (std::size_t i = 0; i < values.size(); ++i)
      if (std::isnan(values[i]))
        throw std::runtime_error(path + ": query " + std::to_string(i / stride) + " is NaN");
    return values;
  }
  CsvReader csv(path, {reinterpret_cast<const char*>(input.bytes.data()), input.bytes.size()});
  std::vector<std::string_view> fields;
  for (bool first = true; csv.next(fields); first = false) {
    double v = 0;
    if (first && !fields.empty() && !parse_double(fields[0], v)) continue;  // a header row
    if (fields.size() < stride)
      throw std::runtime_error(csv.where("expected " + std::to_string(stride) + " numbers, got " +
                                         std::to_string(fields.size()) + " fields"));
    for (std::size_t k = 0; k < stride; ++k) {
      if (!parse_double(fields[k], v))
        throw std::runtime_error(csv.where("field " + std::to_string(k + 1) + " '" +
                                           std::string(fields[k]) + "' is not a finite number"));
      values.push_back(v);
    }
  }
  return values;
}

void append_number(std::string& out, double v) {
  char text[32];
  out.append(text, std::to_chars(text, text + sizeof text, v).ptr);
}

void append_row(std::string& out, std::size_t query, std::uint64_t row) {
  out += std::to_string(query);
  out += ',';
  out += std::to_string(row);
}

// Runs answer(i, text) for every query in parallel batches; concatenated in query order, so
// the output does not depend on the thread count.
template <class Answer>
std::string answer_all(std::size_t count, unsigned threads, Answer answer) {
  std::vector<std::string> parts((count + kBatch - 1) / kBatch);
  parallel_for(parts.size(), threads, [&](std::size_t b) {
    for (std::size_t i = b * kBatch; i < std::min(count, (b + 1) * kBatch); ++i)
      answer(i, parts[b]);
  });
  std::string out;
  for (const auto& part : parts) out += part;
  return out;
}

std::string range_answers(const Point2Queries& q, const RowOf& row_of, const std::vector<double>& v,
                          unsigned threads) {
  return "box_index,point_index\n" +
         answer_all(v.size() / 4, threads, [&](std::size_t i, std::string& out) {
           std::vector<std::uint32_t> found;
           q.range({{v[4 * i], v[4 * i + 1]}, {v[4 * i + 2], v[4 * i + 3]}}, found);
           std::uint64_t last = ~std::uint64_t{0};
           for (const auto point : found) {
             const std::uint64_t row = row_of(point);
             if (row == last) continue;  // a multipoint feature's points: the row once
             last = row;
             append_row(out, i, row);
             out += '\n';
           }
         });
}

std::string neighbor_answers(const Point2Queries& q, const RowOf& row_of,
                             const Points2dQueryArgs& args, const std::vector<double>& v) {
  return "query_index,point_index,distance\n" +
         answer_all(v.size() / 2, args.threads, [&](std::size_t i, std::string& out) {
           const format::Double2 p{v[2 * i], v[2 * i + 1]};
           std::vector<Neighbor2> found;
           if (args.op == "knn2d") {
             found.resize(args.k);
             found.resize(q.nearest(p, found));
           } else {
             q.within_radius(p, args.radius, found);
           }
           for (const Neighbor2& n : found) {
             append_row(out, i, row_of(n.index));
             out += ',';
             append_number(out, std::sqrt(n.distance_squared));
             out += '\n';
           }
         });
}

}  // namespace

bool is_points2d_op(const std::string& op) {
  return op == "range" || op == "knn2d" || op == "radius2d";
}

int run_points2d_query(const Points2dQueryArgs& args) {
  try {
    const Blob blob = Blob::open_file(args.blob);
    const ChosenStructure chosen = choose_structure(blob, args.accel, &StructureView::points2,
                                                    "answer 2D point range and neighbour queries");
    const RowOf row_of{blob.point_table().feature_points};
    const std::vector<double> values = read_queries(args.in, args.op == "range" ? 4 : 2);
    const Point2Queries& q = *chosen.view->points2();
    const std::string out = args.op == "range" ? range_answers(q, row_of, values, args.threads)
                                               : neighbor_answers(q, row_of, args, values);
    write_file_atomically(args.out, std::as_bytes(std::span(out.data(), out.size())));
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "kiln query: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace kiln::cli
