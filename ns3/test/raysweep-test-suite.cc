// Tests of the Raysweep ns-3 models against a synthetic table whose every gain,
// LoS class and position is a closed-form function of (pair, frame), written by
// the project's own table writer. Run by ctest (ns3_models):
//   raysweep-ns3-test --suite=raysweep [--verbose]
// and, for the example's end-to-end test, the same table:
//   raysweep-ns3-test --write-table PATH
#include "ns3/raysweep-helper.h"
#include "ns3/simulator.h"
#include "ns3/constant-position-mobility-model.h"
#include "ns3/spectrum-model.h"
#include "ns3/spectrum-signal-parameters.h"
#include "ns3/test.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

using namespace ns3;
namespace rg = raysweep::generators;

namespace
{

// 4 vehicles, 10 frames at 10 Hz from t0; v3 joins at frame 5. Vehicle i is at
// x = 20 i + f, y = 5 i, z = 0.5, moving at (10, 0, 0) m/s.
constexpr double kT0 = 10.0, kDt = 0.1;
constexpr uint32_t kNodes = 4, kFrames = 10, kJoin = 5, kBands = 4;
constexpr double kBandWidth = 2.5e6, kCarrier = 5.9e9;

bool
Present(uint32_t node, uint32_t f)
{
    return node != 3 || f >= kJoin;
}

double
Gain(uint32_t a, uint32_t b, uint32_t f)
{
    return -60.0 - 10.0 * a - b - 0.5 * f;
}

uint8_t
Los(uint32_t a, uint32_t b, uint32_t f)
{
    return static_cast<uint8_t>((a + b + f) % 3);
}

double
BandGain(uint32_t a, uint32_t b, uint32_t f, uint32_t k)
{
    return Gain(a, b, f) + k - 1.5;
}

double
BandCenter(uint32_t k)
{
    return kCarrier + (k - 1.5) * kBandWidth;
}

void
WriteTable(const std::string& path)
{
    rg::Ns3TableHeader h;
    h.raysweep_version = "test";
    h.git_hash = "test";
    h.config = nlohmann::json::object();
    h.inputs = nlohmann::json::array();
    h.provenance = {{"stage", "raysweep-ns3-test"}};
    h.carrier_hz = kCarrier;
    h.bandwidth_hz = 10e6;
    h.gain_source = rg::GainSource::cfr;
    rg::Ns3TableBands bands;
    bands.subcarriers_per_band = 16;
    bands.band_width_hz = kBandWidth;
    for (uint32_t k = 0; k < kBands; ++k)
    {
        bands.center_hz.push_back(BandCenter(k));
    }
    rg::Ns3TableWriter w(path, h, bands);
    for (uint32_t f = 0; f < kFrames; ++f)
    {
        std::vector<rg::NodeState> states;
        std::vector<rg::Ns3Pair> pairs;
        std::vector<float> bg;
        for (uint32_t n = 0; n < kNodes; ++n)
        {
            if (Present(n, f))
            {
                rg::NodeState s;
                s.node = n;
                s.x = 20.0 * n + f;
                s.y = 5.0 * n;
                s.z = 0.5;
                s.vx = 10;
                states.push_back(s);
            }
        }
        for (uint32_t a = 0; a < kNodes; ++a)
        {
            for (uint32_t b = a + 1; b < kNodes; ++b)
            {
                if (Present(a, f) && Present(b, f))
                {
                    pairs.push_back({a, b, static_cast<float>(Gain(a, b, f)), Los(a, b, f)});
                    for (uint32_t k = 0; k < kBands; ++k)
                    {
                        bg.push_back(static_cast<float>(BandGain(a, b, f, k)));
                    }
                }
            }
        }
        w.add_frame(kT0 + kDt * f, states, pairs, bg);
    }
    std::vector<rg::NodeInfo> nodes(kNodes);
    for (uint32_t n = 0; n < kNodes; ++n)
    {
        nodes[n].id = "v" + std::to_string(n);
    }
    w.finish(nodes);
}

std::string
FixtureTable()
{
    static const std::string path = [] {
        const std::string p = (std::filesystem::temp_directory_path() /
                               ("raysweep-ns3-test-" + std::to_string(::getpid()) + ".h5"))
                                  .string();
        WriteTable(p);
        return p;
    }();
    return path;
}

// Runs fn at simulation time t (s).
void
At(double t, std::function<void()> fn)
{
    Simulator::Schedule(Seconds(t), fn);
}

// Runs fn in a child process; returns (terminated abnormally or non-zero exit, stderr).
std::pair<bool, std::string>
InChild(const std::function<void()>& fn)
{
    int fds[2];
    if (::pipe(fds) != 0)
    {
        return {false, "pipe failed"};
    }
    std::fflush(nullptr);
    const pid_t pid = ::fork();
    if (pid == 0)
    {
        ::close(fds[0]);
        ::dup2(fds[1], 2);
        ::dup2(fds[1], 1);
        fn();
        std::fflush(nullptr);
        ::_exit(0);
    }
    ::close(fds[1]);
    std::string out;
    char buf[4096];
    for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;)
    {
        out.append(buf, static_cast<std::size_t>(n));
    }
    ::close(fds[0]);
    int status = 0;
    ::waitpid(pid, &status, 0);
    const bool failed = WIFSIGNALED(status) || (WIFEXITED(status) && WEXITSTATUS(status) != 0);
    return {failed, out};
}

class LossTestCase : public TestCase
{
  public:
    LossTestCase()
        : TestCase("rx power = tx power + table gain, sample and hold, reciprocity, interpolation")
    {
    }

  private:
    void DoRun() override
    {
        RaysweepHelper rs(FixtureTable());
        NodeContainer nodes = rs.CreateNodes();
        Ptr<RaysweepPropagationLossModel> hold = rs.CreatePropagationLossModel(false);
        Ptr<RaysweepPropagationLossModel> lin = rs.CreatePropagationLossModel(true);
        auto mob = [&](uint32_t i) { return nodes.Get(i)->GetObject<MobilityModel>(); };
        for (uint32_t f = 0; f < kFrames; ++f)
        {
            for (double offset : {0.0, 0.03, 0.0999})
            {
                At(kT0 + kDt * f + offset, [=, this]() {
                    for (uint32_t a = 0; a < kNodes; ++a)
                    {
                        for (uint32_t b = 0; b < kNodes; ++b)
                        {
                            if (a == b)
                            {
                                continue;
                            }
                            const double rx = hold->CalcRxPower(17.0, mob(a), mob(b));
                            if (!Present(a, f) || !Present(b, f))
                            {
                                NS_TEST_EXPECT_MSG_EQ(std::isinf(rx) && rx < 0, true,
                                                      "absent node: no channel, not 0 dB");
                                continue;
                            }
                            const uint32_t lo = std::min(a, b), hi = std::max(a, b);
                            NS_TEST_EXPECT_MSG_EQ_TOL(rx, 17.0 + Gain(lo, hi, f), 0.01,
                                                      "sample and hold at frame " << f << " + " << offset << " s");
                            NS_TEST_EXPECT_MSG_EQ_TOL(rx, hold->CalcRxPower(17.0, mob(b), mob(a)), 1e-9,
                                                      "reciprocity");
                            if (f + 1 < kFrames && Present(a, f + 1) && Present(b, f + 1))
                            {
                                const double w = offset / kDt;
                                const double expect =
                                    17.0 + Gain(lo, hi, f) + w * (Gain(lo, hi, f + 1) - Gain(lo, hi, f));
                                NS_TEST_EXPECT_MSG_EQ_TOL(lin->CalcRxPower(17.0, mob(a), mob(b)), expect, 0.01,
                                                          "linear in dB");
                            }
                        }
                    }
                });
            }
        }
        Simulator::Run();
        Simulator::Destroy();
    }
};

class ConditionTestCase : public TestCase
{
  public:
    ConditionTestCase()
        : TestCase("channel condition per pair and time; per-band gains")
    {
    }

  private:
    void DoRun() override
    {
        RaysweepHelper rs(FixtureTable());
        NodeContainer nodes = rs.CreateNodes();
        Ptr<RaysweepChannelConditionModel> cond = rs.CreateChannelConditionModel();
        Ptr<RaysweepSpectrumPropagationLossModel> spec = rs.CreateSpectrumPropagationLossModel();
        auto mob = [&](uint32_t i) { return nodes.Get(i)->GetObject<MobilityModel>(); };
        const ChannelCondition::LosConditionValue expect[] = {ChannelCondition::LOS, ChannelCondition::NLOSv,
                                                              ChannelCondition::NLOS};
        for (uint32_t f = 0; f < kFrames; ++f)
        {
            At(kT0 + kDt * f + 0.05, [=, this]() {
                for (uint32_t a = 0; a < kNodes; ++a)
                {
                    for (uint32_t b = a + 1; b < kNodes; ++b)
                    {
                        if (!Present(a, f) || !Present(b, f))
                        {
                            continue;
                        }
                        NS_TEST_EXPECT_MSG_EQ(cond->GetChannelCondition(mob(a), mob(b))->GetLosCondition(),
                                              expect[Los(a, b, f)], "pair " << a << "," << b << " frame " << f);
                        NS_TEST_EXPECT_MSG_EQ(cond->GetChannelCondition(mob(b), mob(a))->GetLosCondition(),
                                              expect[Los(a, b, f)], "reciprocal condition");
                        for (uint32_t k = 0; k < kBands; ++k)
                        {
                            NS_TEST_EXPECT_MSG_EQ_TOL(spec->GainDb(BandCenter(k) + 0.3 * kBandWidth, mob(a), mob(b)),
                                                      BandGain(a, b, f, k), 0.01, "band " << k);
                        }
                        NS_TEST_EXPECT_MSG_EQ_TOL(spec->GainDb(kCarrier + 40e6, mob(a), mob(b)), Gain(a, b, f), 0.01,
                                                  "outside the bands: wideband gain");
                    }
                }
            });
        }
        // The PSD path: a flat PSD over the 4 table bands comes back scaled per band.
        At(kT0 + 0.05, [=, this]() {
            std::vector<double> centers;
            for (uint32_t k = 0; k < kBands; ++k)
            {
                centers.push_back(BandCenter(k));
            }
            Ptr<SpectrumModel> sm = Create<SpectrumModel>(centers);
            Ptr<SpectrumSignalParameters> params = Create<SpectrumSignalParameters>();
            params->psd = Create<SpectrumValue>(sm);
            *params->psd = 1.0;
            Ptr<SpectrumValue> rx = spec->CalcRxPowerSpectralDensity(params, mob(0), mob(1));
            for (uint32_t k = 0; k < kBands; ++k)
            {
                NS_TEST_EXPECT_MSG_EQ_TOL(10 * std::log10((*rx)[k]), BandGain(0, 1, 0, k), 0.01, "PSD band " << k);
            }
        });
        Simulator::Run();
        Simulator::Destroy();
    }
};

class MobilityTestCase : public TestCase
{
  public:
    MobilityTestCase()
        : TestCase("mobility follows the table's positions and velocities")
    {
    }

  private:
    void DoRun() override
    {
        RaysweepHelper rs(FixtureTable());
        NodeContainer nodes = rs.CreateNodes();
        const auto& t = rs.GetTable()->Data();
        for (uint32_t f = 0; f < kFrames; ++f)
        {
            At(t.time(f), [=, this, &t]() {
                for (uint32_t n = 0; n < kNodes; ++n)
                {
                    if (!Present(n, f))
                    {
                        continue;
                    }
                    const auto* s = t.state(f, n);
                    const Vector p = nodes.Get(n)->GetObject<MobilityModel>()->GetPosition();
                    NS_TEST_EXPECT_MSG_EQ_TOL(p.x, 20.0 * n + f, 1e-9, "x of node " << n << " frame " << f);
                    NS_TEST_EXPECT_MSG_EQ_TOL(p.y, s->y, 1e-9, "y");
                    NS_TEST_EXPECT_MSG_EQ_TOL(p.z, s->z, 1e-9, "z");
                    NS_TEST_EXPECT_MSG_EQ_TOL(nodes.Get(n)->GetObject<MobilityModel>()->GetVelocity().x, 10.0, 1e-6,
                                              "vx");
                }
            });
        }
        // Half-way between frames 2 and 3: linear.
        At(kT0 + 2.5 * kDt, [=, this]() {
            NS_TEST_EXPECT_MSG_EQ_TOL(nodes.Get(1)->GetObject<MobilityModel>()->GetPosition().x, 22.5, 1e-6,
                                      "between frames");
        });
        Simulator::Run();
        Simulator::Destroy();
    }
};

class ErrorTestCase : public TestCase
{
  public:
    ErrorTestCase()
        : TestCase("fatal errors name the file and the node or time")
    {
    }

  private:
    void Expect(const std::function<void()>& fn, const std::vector<std::string>& needles, const std::string& what)
    {
        const auto [failed, out] = InChild(fn);
        NS_TEST_EXPECT_MSG_EQ(failed, true, what << ": the child did not fail; output: " << out);
        for (const auto& n : needles)
        {
            NS_TEST_EXPECT_MSG_NE(out.find(n), std::string::npos, what << ": '" << n << "' not in: " << out);
        }
    }

    void DoRun() override
    {
        const std::string table = FixtureTable();
        // A node that no helper bound.
        Expect(
            [&]() {
                RaysweepHelper rs(table);
                NodeContainer nodes = rs.CreateNodes();
                Ptr<Node> stranger = CreateObject<Node>();
                Ptr<MobilityModel> m = CreateObject<ConstantPositionMobilityModel>();
                stranger->AggregateObject(m);
                Ptr<RaysweepPropagationLossModel> loss = rs.CreatePropagationLossModel();
                At(kT0, [&]() { loss->CalcRxPower(0, nodes.Get(0)->GetObject<MobilityModel>(), m); });
                Simulator::Run();
            },
            {table, "node " + std::to_string(kNodes), "not bound"},
            "unknown node");
        // A time before the first frame and one after the last frame's hold.
        for (double t : {kT0 - 0.5, kT0 + kDt * kFrames + 0.5})
        {
            Expect(
                [&]() {
                    RaysweepHelper rs(table);
                    NodeContainer nodes = rs.CreateNodes();
                    Ptr<RaysweepPropagationLossModel> loss = rs.CreatePropagationLossModel();
                    At(t, [&]() {
                        loss->CalcRxPower(0, nodes.Get(0)->GetObject<MobilityModel>(),
                                          nodes.Get(1)->GetObject<MobilityModel>());
                    });
                    Simulator::Run();
                },
                {table, "outside the table"},
                "time " + std::to_string(t));
        }
        // Missing and corrupt files.
        const std::string missing = table + ".missing";
        Expect([&]() { RaysweepHelper rs(missing); }, {missing, "no such file"}, "missing file");
        const std::string corrupt = table + ".corrupt.h5";
        {
            std::ifstream in(table, std::ios::binary);
            std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
            bytes.resize(bytes.size() / 2);
            std::ofstream(corrupt, std::ios::binary) << bytes;
        }
        Expect([&]() { RaysweepHelper rs(corrupt); }, {corrupt}, "truncated file");
        std::filesystem::remove(corrupt);
    }
};

class RaysweepTestSuite : public TestSuite
{
  public:
    RaysweepTestSuite()
        : TestSuite("raysweep", UNIT)
    {
        AddTestCase(new LossTestCase, TestCase::QUICK);
        AddTestCase(new ConditionTestCase, TestCase::QUICK);
        AddTestCase(new MobilityTestCase, TestCase::QUICK);
        AddTestCase(new ErrorTestCase, TestCase::QUICK);
    }
};

RaysweepTestSuite g_raysweepTestSuite;

} // namespace

int
main(int argc, char* argv[])
{
    if (argc == 3 && std::string(argv[1]) == "--write-table")
    {
        WriteTable(argv[2]);
        return 0;
    }
    const int rc = TestRunner::Run(argc, argv);
    std::error_code ec;
    std::filesystem::remove(FixtureTable(), ec);
    return rc;
}
