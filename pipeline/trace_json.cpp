#include "pipeline/trace_json.hpp"

#include "pipeline/json_stream.hpp"

#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>

namespace raysweep::pipeline {

namespace {

// JSON has no infinities: a pair without paths reports null gains.
void db_or_null(JsonStream& js, std::string_view key, double linear) {
  js.key(key);
  if (linear > 0) js.value(tracer::to_db(linear));
  else js.json_text("null");
}

// Object and material names as JSON strings, quoted once: they repeat in
// every interaction, and Sionna scenes' names carry UTF-8 that only dump()
// may vouch for.
struct QuotedNames {
  std::vector<std::string> objects, materials;
  explicit QuotedNames(const TraceDocument& doc) {
    for (const auto& n : *doc.objects) objects.push_back(nlohmann::json(n).dump());
    for (const auto& n : *doc.materials) materials.push_back(nlohmann::json(n).dump());
  }
};

// The keys of every path and interaction, quoted once.
struct PathKeys {
  using K = JsonStream::Key;
  K a_im{"a_im"}, a_re{"a_re"}, doppler_hz{"doppler_hz"}, interactions{"interactions"}, material{"material"},
      object{"object"}, point{"point"}, type{"type"}, phi_r{"phi_r"}, phi_t{"phi_t"}, tau_s{"tau_s"},
      theta_r{"theta_r"}, theta_t{"theta_t"};
};

void write_path(JsonStream& js, const tracer::Path& path, const QuotedNames& names) {
  static const PathKeys k;
  js.begin_object().field(k.a_im, path.a.imag()).field(k.a_re, path.a.real()).field(k.doppler_hz, path.doppler_hz);
  js.key(k.interactions).begin_array();
  for (const auto& i : path.interactions)
    js.begin_object()
        .key(k.material).json_text(names.materials.at(i.material))
        .key(k.object).json_text(names.objects.at(i.object))
        .number_array(k.point, i.point)
        .field(k.type, tracer::interaction_name(i.type))
        .end_object();
  js.end_array();
  js.field(k.phi_r, path.phi_r).field(k.phi_t, path.phi_t).field(k.tau_s, path.tau_s);
  js.field(k.theta_r, path.theta_r).field(k.theta_t, path.theta_t).end_object();
}

void write_cfr(JsonStream& js, const tracer::PairResult& p, const tracer::OfdmGrid& grid) {
  const auto h = tracer::frequency_response(p.paths, grid);
  js.key("cfr_im").begin_array();
  for (const auto& v : h) js.value(v.imag());
  js.end_array().key("cfr_re").begin_array();
  for (const auto& v : h) js.value(v.real());
  js.end_array();
}

// Keys in the order std::map sorts them (the stream checks it).
void write_pair(JsonStream& js, const tracer::PairResult& p, const TraceDocument& doc, const QuotedNames& names) {
  js.begin_object().key("blockers").begin_array();
  for (auto b : p.blockers) js.json_text(names.objects.at(b));
  js.end_array().field("candidates", p.candidates);
  if (doc.grid) write_cfr(js, p, *doc.grid);
  js.field("delay_s", p.stats.first_delay_s)
      .field("dropped_transmission_cap", p.dropped_transmission_cap)
      .field("fresnel_clearance", p.fresnel_clearance)
      .field("los_class", tracer::los_class_name(p.los_class))
      .field("los_class_fresnel", tracer::los_class_name(p.fresnel_class))
      .field("n_paths", p.paths.size())
      .field("out_of_range", p.out_of_range);
  db_or_null(js, "path_gain_db", p.stats.gain_coherent);
  db_or_null(js, "path_gain_incoherent_db", p.stats.gain_incoherent);
  js.key("paths").begin_array();
  for (const auto& path : p.paths) write_path(js, path, names);
  js.end_array();
  js.field("paths_below_threshold", p.dropped_threshold)
      .field("rms_delay_spread_s", p.stats.rms_delay_spread_s)
      .field("rx", (*doc.nodes)[p.rx].id)
      .field("tx", (*doc.nodes)[p.tx].id)
      .field("vehicle_loss_db", p.vehicle_loss_db)
      .end_object();
}

// Formatting is most of the writing (numbers' shortest forms): chunks of
// pairs are formatted on every core and spliced in order, so the bytes do not
// depend on the thread count, and a bounded number of chunks is in memory.
void write_pairs(JsonStream& js, const TraceDocument& doc) {
  constexpr std::size_t kChunk = 16;
  const auto& pairs = doc.snapshot->pairs;
  const std::size_t chunks = (pairs.size() + kChunk - 1) / kChunk;
  js.key("pairs").begin_array();
  const JsonStream::Fragment at{js.depth()};
  const QuotedNames names(doc);
  std::size_t next = 0;
  tbb::parallel_pipeline(
      4 * static_cast<std::size_t>(tbb::this_task_arena::max_concurrency()),
      tbb::make_filter<void, std::size_t>(tbb::filter_mode::serial_in_order,
                                          [&](tbb::flow_control& fc) -> std::size_t {
                                            if (next == chunks) fc.stop();
                                            return next++;
                                          }) &
          tbb::make_filter<std::size_t, JsonStream::Text>(tbb::filter_mode::parallel,
                                                     [&](std::size_t c) {
                                                       JsonStream part(at, 1);
                                                       const std::size_t end = std::min(pairs.size(), (c + 1) * kChunk);
                                                       for (std::size_t i = c * kChunk; i < end; ++i)
                                                         write_pair(part, pairs[i], doc, names);
                                                       return part.take();
                                                     }) &
          tbb::make_filter<JsonStream::Text, void>(tbb::filter_mode::serial_in_order,
                                              [&](const JsonStream::Text& text) { js.splice(text); }));
  js.end_array();
}

void write_nodes(JsonStream& js, const std::vector<tracer::Node>& nodes) {
  js.key("nodes").begin_array();
  for (const auto& n : nodes)
    js.begin_object()
        .field("id", n.id)
        .number_array("position", n.position)
        .field("vehicle", n.vehicle)
        .number_array("velocity", n.velocity)
        .end_object();
  js.end_array();
}

nlohmann::json stats_json(const tracer::SnapshotStats& s) {
  return {{"rays", s.rays},
          {"candidates", s.candidates},
          {"paths", s.paths},
          {"dropped_transmission_cap", s.dropped_transmission_cap},
          {"paths_below_threshold", s.dropped_threshold},
          {"out_of_range_pairs", s.out_of_range_pairs},
          {"diffraction_paths", s.diffraction_paths},
          {"diffuse_paths", s.diffuse_paths}};
}

}  // namespace

void write_trace_json(std::ostream& out, const TraceDocument& doc) {
  JsonStream js(out, 1);
  js.begin_object();
  if (doc.grid)
    js.field("cfr_grid", nlohmann::json{{"spec", doc.cfr_spec},
                                        {"carrier_hz", doc.grid->carrier_hz},
                                        {"subcarrier_spacing_hz", doc.grid->subcarrier_spacing_hz},
                                        {"n_subcarriers", doc.grid->n_subcarriers},
                                        {"first_offset_hz", doc.grid->offset_hz(0)}});
  write_nodes(js, *doc.nodes);
  write_pairs(js, doc);
  js.field("provenance", doc.provenance).field("radio", doc.radio).field("stats", stats_json(doc.snapshot->stats));
  js.end_object();
  out << '\n';
}

}  // namespace raysweep::pipeline
