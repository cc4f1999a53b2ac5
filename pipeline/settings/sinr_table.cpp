#include "pipeline/settings/tables.hpp"

#include "generators/sinr/types.hpp"
#include "pipeline/settings/sinr.hpp"
#include "pipeline/settings/values.hpp"

namespace raysweep::pipeline {

using json = nlohmann::json;
using namespace schema;

namespace {

// [[sinr_db, bler], ...], increasing SINR (SinrConfig::check).
Value<std::vector<std::pair<double, double>>> bler_curve() {
  auto p = numbers<2>();
  Value<std::pair<double, double>> pt;
  pt.type = "[sinr_db, bler] pair";
  pt.expect = "a [sinr_db, bler] pair";
  pt.read = [p](const toml::node& n, const At& at) {
    const auto a = p.read(n, at);
    return std::make_pair(a[0], a[1]);
  };
  pt.write = [](const std::pair<double, double>& x) { return json::array({x.first, x.second}); };
  return list(pt);
}

}  // namespace

// --- [sinr] -----------------------------------------------------------------

const Table<SinrSettings>& sinr_table() {
  static const Table<SinrSettings> t = [] {
    namespace gs = generators::sinr;
    Table<SinrSettings> t("sinr",
                          "`raysweep sinr` and `run`: 802.11p and NR-V2X sharing the channel (docs/sinr.md). With "
                          "this table `raysweep run` computes the outcomes and their report.");
    t.key("enabled", boolean(), FIELD(enabled), "", "`run`: compute the outcomes");
    t.key("seed", integer<std::uint64_t>(), FIELD(config.seed), "", "RAT assignment, schedules and shadowing");
    t.key("begin_s", number(), FIELD(config.begin_s), "s", "simulated window within the channel dataset (-1: all of it)");
    t.key("end_s", number(), FIELD(config.end_s), "s", "(-1: all of it)");
    t.key("nr_fraction", number(between(0, 1)), FIELD(config.rats.nr_fraction), "",
          "exact share of NR-V2X among the vehicles no list assigns");
    t.key("rat_by_vtype",
          map(enumeration<gs::Rat>({{"80211p", gs::Rat::wifi80211p}, {"nrv2x", gs::Rat::nr_v2x}, {"none", gs::Rat::none}}),
              "vType"),
          FIELD(config.rats.by_vtype), "", "the RAT of every vehicle of a vType");
    t.key("nr_ids", list(text()), FIELD(config.rats.nr_ids), "", "vehicles that use NR-V2X");
    t.key("wifi_ids", list(text()), FIELD(config.rats.wifi_ids), "", "vehicles that use 802.11p");
    t.key("silent_ids", list(text()), FIELD(config.rats.silent_ids), "", "vehicles that send nothing");
    t.key("active_vehicles", integer<std::uint32_t>(), FIELD(config.rats.active_vehicles), "",
          "the first N vehicles to appear take part (0: all); the others only block and reflect");
    t.key("rats_enabled", choice({"both", "80211p-only", "nrv2x-only"}), FIELD(config.rats.enabled), "",
          "silence one RAT after the assignment (the same vehicles without coexistence)");
    t.key("cam", boolean(), FIELD(config.cam.enabled), "", "send CAMs (ETSI EN 302 637-2 rules)");
    t.key("cam_bytes", integer<std::uint32_t>(at_least(1)), FIELD(config.cam.bytes), "bytes", "CAM size");
    t.key("cam_low_frequency_bytes", integer<std::uint32_t>(), FIELD(config.cam.low_frequency_bytes), "bytes",
          "added when the low-frequency container is due (every 500 ms)");
    t.key("cam_t_gen_min_s", number(above(0)), FIELD(config.cam.t_gen_min_s), "s", "T_GenCamMin");
    t.key("cam_t_gen_max_s", number(above(0)), FIELD(config.cam.t_gen_max_s), "s", "T_GenCamMax");
    t.key("cam_check_period_s", number(above(0)), FIELD(config.cam.check_period_s), "s", "T_CheckCamGen");
    t.key("cpm", boolean(), FIELD(config.cpm.enabled), "", "also send periodic CPMs");
    t.key("cpm_period_s", number(above(0)), FIELD(config.cpm.period_s), "s", "CPM period");
    t.key("cpm_bytes", integer<std::uint32_t>(), FIELD(config.cpm.bytes), "bytes", "CPM size");
    t.key("wifi_data_rate_bps", number(above(0)), FIELD(config.wifi.data_rate_bps), "bit/s",
          "802.11p rate: 3, 4.5, 6, 9, 12, 18, 24 or 27 Mb/s");
    t.key("wifi_access_category", choice({"BK", "BE", "VI", "VO"}), FIELD(config.wifi_mac.access_category), "",
          "EDCA access category");
    t.key("wifi_cca_signal_dbm", number(), FIELD(config.wifi_mac.cca_signal_dbm), "dBm",
          "an 802.11p preamble above this makes the medium busy");
    t.key("wifi_cca_energy_dbm", number(), FIELD(config.wifi_mac.cca_energy_dbm), "dBm",
          "any in-band energy above this makes the medium busy (NR included)");
    t.key("nr_bandwidth_hz", number(above(0)), FIELD(config.nr.bandwidth_hz), "Hz", "NR-V2X channel bandwidth");
    t.key("nr_numerology", integer<int>(between(0, 2)), FIELD(config.nr.numerology), "",
          "mu: subcarrier spacing 15 kHz x 2^mu");
    t.key("nr_subchannel_rbs", integer<int>(between(10, 100)), FIELD(config.nr.subchannel_rbs), "RBs",
          "subchannel size (sl-SubchannelSize)");
    t.key("nr_mcs", integer<int>(between(0, 28)), FIELD(config.nr.mcs), "", "MCS index (TS 38.214 64QAM table)");
    t.key("nr_data_symbols", integer<int>(between(1, 12)), FIELD(config.nr.data_symbols), "",
          "PSSCH symbols per slot carrying data");
    t.key("nr_reservation_period_s", number(above(0)), FIELD(config.nr_mac.reservation_period_s), "s",
          "semi-persistent reservation period (whole slots)");
    t.key("nr_selection", enumeration<bool>({{"random", false}, {"sensing", true}}), FIELD(config.nr_mac.sensing), "",
          "resource selection: random (the paper) or TS 38.214 sensing-based exclusion");
    t.key("nr_sensing_threshold_dbm", number(), FIELD(config.nr_mac.sensing_threshold_dbm), "dBm",
          "RSRP per resource element above which a reserved resource is excluded");
    t.key("nr_keep_probability", number(between(0, 1)), FIELD(config.nr_mac.keep_probability), "",
          "sl-ProbResourceKeep");
    t.key("nr_retransmissions", integer<int>(between(0, 31)), FIELD(config.nr_mac.retransmissions), "",
          "blind retransmissions per packet");
    t.key("tx_power_dbm", number(), FIELD(config.tx_power_dbm), "dBm", "transmit power");
    t.key("sensitivity_dbm", number(), FIELD(config.sensitivity_dbm), "dBm", "weakest decodable power");
    t.key("sinr_threshold_db", number(), FIELD(config.sinr_threshold_db), "dB", "decoded when SINR reaches this");
    t.key("noise_figure_db", number(), FIELD(config.noise_figure_db), "dB", "receiver noise figure");
    t.key("gain_threshold_db", number(), FIELD(config.gain_threshold_db), "dB",
          "inter-RAT interferers count only above this channel gain");
    t.key("wifi_bler", bler_curve(), FIELD(config.wifi_bler), "",
          "802.11p BLER curve [[sinr_db, bler], ...] replacing the threshold");
    t.key("nr_bler", bler_curve(), FIELD(config.nr_bler), "", "NR-V2X BLER curve replacing the threshold");
    t.key("prr_range_m", number(above(0)), FIELD(config.prr_range_m), "m", "receivers within this distance count in PRR");
    t.key("max_receiver_distance_m", number(at_least(0)), FIELD(config.max_receiver_distance_m), "m",
          "0: every present receiver of the RAT gets a row");
    t.key("shadowing", boolean(), FIELD(stochastic.shadowing), "", "3GPP baselines: spatially consistent shadowing");
    t.key("antenna_height_m", number(above(0)), FIELD(stochastic.antenna_height_m), "m", "3GPP baselines: antenna height");
    t.key("blocker_height_m", number(above(0)), FIELD(stochastic.blocker_height_m), "m",
          "TR 37.885 NLOSV blockage: vehicle height");
    t.key("decorrelation_m", number(above(0)), FIELD(stochastic.decorrelation_m), "m",
          "shadowing and LoS-state correlation distance");
    t.key("models",
          list(parsed<generators::sinr::SinrModel>(
                   "string",
                   "\"ray\", \"tr36885\", \"tr37885-urban\" or \"tr37885-highway\", the 3GPP ones optionally "
                   "+ \"+los-from-ray\"",
                   "a channel model name", [](const std::string& s) { return generators::sinr::parse_sinr_model(s); },
                   [](const generators::sinr::SinrModel& m) { return json(m.label()); }),
               1),
          FIELD(models), "", "`run`: the channel models compared; the first is the reference");
    t.key("schedule", enumeration<bool>({{"shared", true}, {"own", false}}), FIELD(shared_schedule), "",
          "`run`: the other models evaluate the reference's transmissions (shared) or draw their own");
    t.key("isolated_runs", boolean(), FIELD(isolated_runs), "", "`run`: also the reference with each RAT alone");
    return t;
  }();
  return t;
}

#undef FIELD

}  // namespace raysweep::pipeline
