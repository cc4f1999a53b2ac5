// raysweep-ns3-cam: a real ns-3 802.11p simulation on a raysweep ns-3 table.
// Every vehicle broadcasts CAM-sized packets at a fixed rate over WAVE / OCB
// (10 MHz, 6 Mb/s, YansWifiPhy with ns-3's NIST OFDM error model); the channel
// (wideband gain per pair and frame) comes from the table through
// RaysweepPropagationLossModel; node positions follow the table.
//
//   raysweep-ns3-cam --table T.h5 --out DIR [--start S] [--duration S] [--packet-bytes N]
//                    [--rate-hz F] [--tx-power-dbm P] [--seed N]
//
// DIR/receptions.csv: one row per (packet, receiver present in the frame) the
// channel evaluated: time_s,tx,rx,tx_power_dbm,rx_power_dbm,los_class,received,distance_m
// (tx, rx: table node ids; received: the receiver's PHY decoded it and its MAC
// delivered it). DIR/summary.json: PRR per distance bin, counts, wall time, the
// settings and the table's provenance.
#include "ns3/core-module.h"
#include "ns3/mobility-module.h"
#include "ns3/network-module.h"
#include "ns3/propagation-module.h"
#include "ns3/wave-mac-helper.h"
#include "ns3/wifi-80211p-helper.h"
#include "ns3/wifi-module.h"

#include "ns3/raysweep-helper.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

using namespace ns3;

namespace
{

struct Row
{
    double time, txDbm, rxDbm, distance;
    uint32_t tx, rx;
    uint8_t los;
    bool received;
};

struct Run
{
    Ptr<RaysweepTable> table;
    std::vector<Row> rows;
    std::map<std::pair<uint64_t, uint32_t>, std::size_t> rowOf; // (packet uid, rx) -> row
    uint64_t currentUid = 0;
    bool inTx = false;
    uint64_t sent = 0;
    NodeContainer nodes;
    std::vector<Ptr<Socket>> sockets; // PacketSocket registers raw pointers with its node: keep them alive
};

Run g;

void
OnTxBegin(Ptr<const Packet> p, double)
{
    g.currentUid = p->GetUid();
    g.inTx = true;
}

void
OnRxPower(uint32_t tx, uint32_t rx, double txDbm, double rxDbm, uint8_t los)
{
    if (!g.inTx || los == 255)
    {
        return; // not one of our broadcasts, or the receiver is not on the road
    }
    const double d = g.nodes.Get(tx)->GetObject<MobilityModel>()->GetDistanceFrom(
        g.nodes.Get(rx)->GetObject<MobilityModel>());
    g.rowOf[{g.currentUid, rx}] = g.rows.size();
    g.rows.push_back({Simulator::Now().GetSeconds(), txDbm, rxDbm, d, tx, rx, los, false});
}

void
OnReceive(Ptr<Socket> socket)
{
    const uint32_t rx = socket->GetNode()->GetId();
    while (Ptr<Packet> p = socket->Recv())
    {
        auto it = g.rowOf.find({p->GetUid(), rx});
        if (it != g.rowOf.end())
        {
            g.rows[it->second].received = true;
        }
    }
}

void
SendCam(Ptr<Socket> socket, uint32_t node, uint32_t bytes, Time period, Time end)
{
    const auto& t = g.table->Data();
    const auto frame = t.frame_at(Simulator::Now().GetSeconds());
    if (frame && t.state(*frame, node))
    {
        socket->Send(Create<Packet>(bytes));
        ++g.sent;
    }
    if (Simulator::Now() + period < end)
    {
        Simulator::Schedule(period, &SendCam, socket, node, bytes, period, end);
    }
}

// The command line.
struct Settings
{
    std::string tableFile, outDir;
    double start = NAN, duration = NAN, rateHz = 10, txPowerDbm = 23, noiseFigureDb = 9;
    uint32_t packetBytes = 300, seed = 1;
};

// Parses the command line into s; the exit status when it is unusable (0: go on).
int
ParseSettings(int argc, char* argv[], Settings& s)
{
    CommandLine cmd(__FILE__);
    cmd.AddValue("table", "raysweep ns-3 table (.h5)", s.tableFile);
    cmd.AddValue("out", "output folder (receptions.csv, summary.json)", s.outDir);
    cmd.AddValue("start", "simulation start in the table's time (s; default: the first frame)", s.start);
    cmd.AddValue("duration", "simulated time (s; default: to the end of the table)", s.duration);
    cmd.AddValue("packet-bytes", "CAM size (bytes)", s.packetBytes);
    cmd.AddValue("rate-hz", "CAMs per second per vehicle", s.rateHz);
    cmd.AddValue("tx-power-dbm", "transmit power (dBm)", s.txPowerDbm);
    cmd.AddValue("noise-figure-db", "receiver noise figure (dB)", s.noiseFigureDb);
    cmd.AddValue("seed", "run number of ns-3's random streams (send phases, backoff)", s.seed);
    cmd.Parse(RaysweepCommandLineArgs(argc, argv));
    if (s.tableFile.empty() || s.outDir.empty())
    {
        std::cerr << "usage: raysweep-ns3-cam --table T.h5 --out DIR [--start S] [--duration S] "
                     "[--packet-bytes N] [--rate-hz F] [--tx-power-dbm P] [--seed N]\n";
        return 2;
    }
    if (!(s.rateHz > 0) || s.packetBytes == 0 || s.seed == 0)
    {
        std::cerr << "raysweep-ns3-cam: --rate-hz must be > 0, --packet-bytes and --seed >= 1\n";
        return 2;
    }
    return 0;
}

// Fills in the default start and duration from the table's frames; the exit
// status when the interval leaves the table (0: go on).
int
ResolveInterval(const raysweep::generators::Ns3Table& t, Settings& s)
{
    if (t.frames() == 0)
    {
        std::cerr << s.tableFile << ": the table has no frames\n";
        return 2;
    }
    const double first = t.time(0), last = t.time(t.frames() - 1) + t.frame_step();
    if (std::isnan(s.start))
    {
        s.start = first;
    }
    if (std::isnan(s.duration))
    {
        s.duration = last - s.start;
    }
    if (s.start < first || !(s.duration > 0) || s.start + s.duration > last + 1e-9)
    {
        std::cerr << s.tableFile << ": --start " << s.start << " --duration " << s.duration << " leaves the table ("
                  << first << " s .. " << last << " s)\n";
        return 2;
    }
    return 0;
}

// 802.11p devices on every node over a channel whose loss is the table's.
NetDeviceContainer
InstallWifi(RaysweepHelper& rs, const Settings& s)
{
    Ptr<YansWifiChannel> channel = CreateObject<YansWifiChannel>();
    Ptr<RaysweepPropagationLossModel> loss = rs.CreatePropagationLossModel();
    loss->TraceConnectWithoutContext("RxPower", MakeCallback(&OnRxPower));
    channel->SetPropagationLossModel(loss);
    channel->SetPropagationDelayModel(CreateObject<ConstantSpeedPropagationDelayModel>());
    YansWifiPhyHelper phy;
    phy.SetChannel(channel);
    phy.Set("TxPowerStart", DoubleValue(s.txPowerDbm));
    phy.Set("TxPowerEnd", DoubleValue(s.txPowerDbm));
    phy.Set("RxNoiseFigure", DoubleValue(s.noiseFigureDb));
    phy.SetErrorRateModel("ns3::NistErrorRateModel");
    NqosWaveMacHelper mac = NqosWaveMacHelper::Default();
    Wifi80211pHelper wifi = Wifi80211pHelper::Default();
    wifi.SetRemoteStationManager("ns3::ConstantRateWifiManager",
                                 "DataMode", StringValue("OfdmRate6MbpsBW10MHz"),
                                 "ControlMode", StringValue("OfdmRate6MbpsBW10MHz"),
                                 "NonUnicastMode", StringValue("OfdmRate6MbpsBW10MHz"));
    NetDeviceContainer devices = wifi.Install(phy, mac, g.nodes);
    for (uint32_t i = 0; i < devices.GetN(); ++i)
    {
        Ptr<WifiNetDevice> dev = DynamicCast<WifiNetDevice>(devices.Get(i));
        dev->GetPhy()->TraceConnectWithoutContext("PhyTxBegin", MakeCallback(&OnTxBegin));
    }
    return devices;
}

// A broadcast socket pair per node; each node's first CAM at a random phase of the period.
void
ScheduleCams(const NetDeviceContainer& devices, const Settings& s, Time tStart, Time tEnd)
{
    PacketSocketHelper sockets;
    sockets.Install(g.nodes);
    Ptr<UniformRandomVariable> phase = CreateObject<UniformRandomVariable>();
    const Time period = Seconds(1.0 / s.rateHz);
    for (uint32_t i = 0; i < g.nodes.GetN(); ++i)
    {
        PacketSocketAddress addr;
        addr.SetSingleDevice(devices.Get(i)->GetIfIndex());
        addr.SetPhysicalAddress(devices.Get(i)->GetBroadcast());
        addr.SetProtocol(0x8947); // GeoNetworking EtherType
        Ptr<Socket> rx = Socket::CreateSocket(g.nodes.Get(i), PacketSocketFactory::GetTypeId());
        rx->Bind(addr);
        rx->SetRecvCallback(MakeCallback(&OnReceive));
        Ptr<Socket> tx = Socket::CreateSocket(g.nodes.Get(i), PacketSocketFactory::GetTypeId());
        tx->Bind();
        tx->Connect(addr);
        tx->SetAllowBroadcast(true);
        g.sockets.push_back(rx);
        g.sockets.push_back(tx);
        Simulator::Schedule(tStart + Seconds(phase->GetValue(0, 1.0 / s.rateHz)), &SendCam, tx, i, s.packetBytes,
                            period, tEnd);
    }
}

// DIR/receptions.csv, written whole before it takes its name; false when it cannot be written.
bool
WriteReceptions(const std::string& outDir, const raysweep::generators::Ns3Table& t)
{
    const std::string csv = outDir + "/receptions.csv";
    {
        std::ofstream o(csv + ".tmp");
        o << "time_s,tx,rx,tx_power_dbm,rx_power_dbm,los_class,received,distance_m\n";
        char buf[256];
        const char* los[] = {"LOS", "NLOSv", "NLOS"};
        for (const Row& r : g.rows)
        {
            std::snprintf(buf, sizeof buf, "%.6f,%s,%s,%.2f,%.3f,%s,%d,%.2f\n", r.time, t.node_ids()[r.tx].c_str(),
                          t.node_ids()[r.rx].c_str(), r.txDbm, r.rxDbm, los[std::min<int>(r.los, 2)],
                          r.received ? 1 : 0, r.distance);
            o << buf;
        }
        if (!o.flush())
        {
            std::cerr << csv << ": cannot write\n";
            return false;
        }
    }
    std::filesystem::rename(csv + ".tmp", csv);
    return true;
}

// The receptions' PRR in distance bins of binM metres; *received counts the received ones.
nlohmann::json
PrrByDistance(double binM, uint64_t* received)
{
    std::map<int, std::pair<uint64_t, uint64_t>> bins;
    for (const Row& r : g.rows)
    {
        auto& b = bins[static_cast<int>(r.distance / binM)];
        ++b.first;
        b.second += r.received ? 1 : 0;
        *received += r.received ? 1 : 0;
    }
    nlohmann::json prr = nlohmann::json::array();
    for (const auto& [k, b] : bins)
    {
        prr.push_back({{"distance_min_m", k * binM},
                       {"distance_max_m", (k + 1) * binM},
                       {"receptions", b.first},
                       {"received", b.second},
                       {"prr", static_cast<double>(b.second) / static_cast<double>(b.first)}});
    }
    return prr;
}

// DIR/summary.json: counts, PRR (overall and by distance), settings, the
// table's provenance and the wall time since wallStart.
nlohmann::json
WriteSummary(const Settings& s, const raysweep::generators::Ns3Table& t,
             std::chrono::steady_clock::time_point wallStart)
{
    const double binM = 25;
    uint64_t received = 0;
    const nlohmann::json prr = PrrByDistance(binM, &received);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wallStart).count();
    nlohmann::json summary = {
        {"table", s.tableFile},
        {"table_provenance", t.provenance()},
        {"settings",
         {{"start_s", s.start},
          {"duration_s", s.duration},
          {"packet_bytes", s.packetBytes},
          {"rate_hz", s.rateHz},
          {"tx_power_dbm", s.txPowerDbm},
          {"noise_figure_db", s.noiseFigureDb},
          {"seed", s.seed},
          {"phy", "YansWifiPhy, NistErrorRateModel, 802.11p OCB 10 MHz, OfdmRate6MbpsBW10MHz"},
          {"ns3_version", "3.37"}}},
        {"packets_sent", g.sent},
        {"receptions", g.rows.size()},
        {"received", received},
        {"prr", g.rows.empty() ? 0.0 : static_cast<double>(received) / static_cast<double>(g.rows.size())},
        {"prr_bin_m", binM},
        {"prr_by_distance", prr},
        {"wall_seconds", wall}};
    const std::string js = s.outDir + "/summary.json";
    {
        std::ofstream o(js + ".tmp");
        o << summary.dump(1) << "\n";
    }
    std::filesystem::rename(js + ".tmp", js);
    return summary;
}

} // namespace

int
main(int argc, char* argv[])
{
    const auto wallStart = std::chrono::steady_clock::now();
    Settings s;
    if (const int status = ParseSettings(argc, argv, s))
    {
        return status;
    }
    RngSeedManager::SetSeed(1);
    RngSeedManager::SetRun(s.seed);

    RaysweepHelper rs(s.tableFile);
    g.table = rs.GetTable();
    const auto& t = g.table->Data();
    if (const int status = ResolveInterval(t, s))
    {
        return status;
    }
    const Time tStart = Seconds(s.start), tEnd = Seconds(s.start + s.duration);

    g.nodes = rs.CreateNodes();
    const NetDeviceContainer devices = InstallWifi(rs, s);
    ScheduleCams(devices, s, tStart, tEnd);
    Simulator::Stop(tEnd);
    Simulator::Run();
    Simulator::Destroy();
    g.sockets.clear();

    std::filesystem::create_directories(s.outDir);
    if (!WriteReceptions(s.outDir, t))
    {
        return 1;
    }
    const nlohmann::json summary = WriteSummary(s, t, wallStart);
    std::cout << s.outDir << ": " << g.sent << " packets, " << g.rows.size() << " receptions, PRR "
              << summary["prr"].get<double>() << ", " << summary["wall_seconds"].get<double>() << " s\n";
    return 0;
}
