#include "raysweep-propagation-loss-model.h"

#include "ns3/boolean.h"
#include "ns3/log.h"
#include "ns3/simulator.h"
#include "ns3/string.h"
#include "ns3/trace-source-accessor.h"

#include <limits>

namespace ns3
{

NS_LOG_COMPONENT_DEFINE("RaysweepPropagationLossModel");
NS_OBJECT_ENSURE_REGISTERED(RaysweepPropagationLossModel);

TypeId
RaysweepPropagationLossModel::GetTypeId()
{
    static TypeId tid =
        TypeId("ns3::RaysweepPropagationLossModel")
            .SetParent<PropagationLossModel>()
            .SetGroupName("Raysweep")
            .AddConstructor<RaysweepPropagationLossModel>()
            .AddAttribute("TableFile",
                          "raysweep ns-3 table (.h5, format raysweep-ns3-table)",
                          StringValue(""),
                          MakeStringAccessor(&RaysweepPropagationLossModel::m_file),
                          MakeStringChecker())
            .AddAttribute("Interpolation",
                          "false: sample and hold (the frame with the largest time <= now); "
                          "true: linear in dB between that frame and the next",
                          BooleanValue(false),
                          MakeBooleanAccessor(&RaysweepPropagationLossModel::m_interpolate),
                          MakeBooleanChecker())
            .AddTraceSource("RxPower",
                            "every evaluation: tx, rx (table nodes), tx and rx power (dBm), LoS class",
                            MakeTraceSourceAccessor(&RaysweepPropagationLossModel::m_rxPowerTrace),
                            "ns3::RaysweepPropagationLossModel::RxPowerTracedCallback");
    return tid;
}

RaysweepPropagationLossModel::RaysweepPropagationLossModel() = default;

Ptr<RaysweepTable>
RaysweepPropagationLossModel::GetTable() const
{
    if (!m_table)
    {
        m_table = RaysweepTable::Get(m_file);
    }
    return m_table;
}

double
RaysweepPropagationLossModel::DoCalcRxPower(double txPowerDbm, Ptr<MobilityModel> a, Ptr<MobilityModel> b) const
{
    Ptr<RaysweepTable> t = GetTable();
    const uint32_t tx = t->IndexOf(a);
    const uint32_t rx = t->IndexOf(b);
    const RaysweepChannel c = t->Lookup(tx, rx, Simulator::Now(), m_interpolate);
    const double rxDbm = c.present ? txPowerDbm + c.gainDb : -std::numeric_limits<double>::infinity();
    m_rxPowerTrace(tx, rx, txPowerDbm, rxDbm, c.present ? c.losClass : uint8_t{255});
    return rxDbm;
}

int64_t
RaysweepPropagationLossModel::DoAssignStreams(int64_t)
{
    return 0;
}

} // namespace ns3
