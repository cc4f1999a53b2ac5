// raysweep-ns3-bench: the cost of the ns-3 table. For a table file (or a
// synthetic table of N vehicles all present in F frames, written first):
// file size and bytes per pair-frame, load time (median of 5 loads), memory of
// the loaded table, and the time per RaysweepPropagationLossModel::CalcRxPower
// call over random pairs and times (median of 7 runs of 200000 calls).
//   raysweep-ns3-bench --table=T.h5
//   raysweep-ns3-bench --table=/tmp/t120.h5 --synthetic-vehicles=120 --frames=600
#include "ns3/core-module.h"

#include "ns3/raysweep-helper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <random>

using namespace ns3;
namespace rg = raysweep::generators;

namespace
{

double
Median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// N vehicles on a 2 km straight road at 10 Hz; gain: free-space-like in distance plus a
// deterministic pseudo-random term, LoS class from the same draw (realistic entropy).
void
WriteSynthetic(const std::string& path, uint32_t n, uint32_t frames)
{
    rg::Ns3TableHeader h;
    h.raysweep_version = "bench";
    h.git_hash = "bench";
    h.config = {{"synthetic_vehicles", n}, {"frames", frames}};
    h.inputs = nlohmann::json::array();
    h.provenance = {{"stage", "raysweep-ns3-bench synthetic"}};
    h.carrier_hz = 5.9e9;
    h.bandwidth_hz = 10e6;
    rg::Ns3TableWriter w(path, h, {});
    std::mt19937 rng(1);
    std::normal_distribution<float> shadow(0, 6);
    std::vector<rg::NodeState> st(n);
    std::vector<rg::Ns3Pair> pairs;
    for (uint32_t f = 0; f < frames; ++f)
    {
        for (uint32_t i = 0; i < n; ++i)
        {
            st[i].node = i;
            st[i].x = std::fmod(17.0 * i + 1.3 * f, 2000.0);
            st[i].y = 3.5 * (i % 4);
            st[i].vx = 13;
        }
        pairs.clear();
        for (uint32_t a = 0; a < n; ++a)
        {
            for (uint32_t b = a + 1; b < n; ++b)
            {
                const double d = std::max(1.0, std::hypot(st[a].x - st[b].x, st[a].y - st[b].y));
                const float s = shadow(rng);
                pairs.push_back({a, b, static_cast<float>(-47.9 - 20 * std::log10(d) + s),
                                 static_cast<uint8_t>(s > 3 ? 0 : (s > -3 ? 1 : 2))});
            }
        }
        w.add_frame(0.1 * f, st, pairs, {});
    }
    std::vector<rg::NodeInfo> nodes(n);
    for (uint32_t i = 0; i < n; ++i)
    {
        nodes[i].id = "veh" + std::to_string(i);
    }
    w.finish(nodes);
}

} // namespace

int
main(int argc, char* argv[])
{
    std::string table;
    uint32_t synthetic = 0, frames = 600, calls = 200000;
    CommandLine cmd(__FILE__);
    cmd.AddValue("table", "table .h5 (written first with --synthetic-vehicles)", table);
    cmd.AddValue("synthetic-vehicles", "write a synthetic table of this many vehicles", synthetic);
    cmd.AddValue("frames", "frames of the synthetic table (10 Hz)", frames);
    cmd.AddValue("calls", "CalcRxPower calls per timed run", calls);
    cmd.Parse(RaysweepCommandLineArgs(argc, argv));
    if (table.empty())
    {
        std::cerr << "usage: raysweep-ns3-bench --table=T.h5 [--synthetic-vehicles=N --frames=F]\n";
        return 2;
    }
    if (synthetic > 0)
    {
        WriteSynthetic(table, synthetic, frames);
    }
    std::vector<double> loads;
    std::size_t memory = 0;
    uint64_t pairs = 0;
    for (int i = 0; i < 5; ++i)
    {
        const auto t0 = std::chrono::steady_clock::now();
        const rg::Ns3Table t = rg::Ns3Table::load(table);
        loads.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        memory = t.memory_bytes();
        pairs = t.pair_count();
    }
    const auto bytes = std::filesystem::file_size(table);

    RaysweepHelper rs(table);
    NodeContainer nodes = rs.CreateNodes();
    Ptr<RaysweepPropagationLossModel> loss = rs.CreatePropagationLossModel();
    const auto& t = rs.GetTable()->Data();
    std::vector<Ptr<MobilityModel>> mob;
    for (uint32_t i = 0; i < nodes.GetN(); ++i)
    {
        mob.push_back(nodes.Get(i)->GetObject<MobilityModel>());
    }
    std::vector<double> ns;
    std::mt19937 rng(7);
    const double t0 = t.time(0), t1 = t.time(t.frames() - 1);
    double sink = 0;
    for (int run = 0; run < 7; ++run)
    {
        const double when = t0 + (t1 - t0) * (run + 0.5) / 7;
        Simulator::Schedule(Seconds(when) - Simulator::Now(), [&]() {
            std::uniform_int_distribution<uint32_t> pick(0, nodes.GetN() - 1);
            std::vector<std::pair<uint32_t, uint32_t>> sel(calls);
            for (auto& p : sel)
            {
                p.first = pick(rng);
                do
                {
                    p.second = pick(rng);
                } while (p.second == p.first);
            }
            const auto c0 = std::chrono::steady_clock::now();
            for (const auto& [a, b] : sel)
            {
                sink += loss->CalcRxPower(20.0, mob[a], mob[b]);
            }
            ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - c0).count() /
                         calls);
        });
        Simulator::Run();
    }
    Simulator::Destroy();
    std::printf("table %s: %u nodes, %zu frames, %llu pair-frames, %llu bytes (%.2f bytes per pair-frame)\n",
                table.c_str(), nodes.GetN(), t.frames(), static_cast<unsigned long long>(pairs),
                static_cast<unsigned long long>(bytes), static_cast<double>(bytes) / static_cast<double>(pairs));
    std::printf("load: median %.3f s of 5; memory %.1f MiB (%.2f bytes per pair-frame)\n", Median(loads),
                memory / 1048576.0, static_cast<double>(memory) / static_cast<double>(pairs));
    std::printf("CalcRxPower: median %.1f ns per call (7 runs x %u calls, min %.1f, max %.1f)%s\n", Median(ns), calls,
                *std::min_element(ns.begin(), ns.end()), *std::max_element(ns.begin(), ns.end()),
                std::isnan(sink) ? " " : "");
    return 0;
}
