#include "raysweep-channel-condition-model.h"

#include "ns3/simulator.h"
#include "ns3/string.h"

namespace ns3
{

NS_OBJECT_ENSURE_REGISTERED(RaysweepChannelConditionModel);

TypeId
RaysweepChannelConditionModel::GetTypeId()
{
    static TypeId tid = TypeId("ns3::RaysweepChannelConditionModel")
                            .SetParent<ChannelConditionModel>()
                            .SetGroupName("Raysweep")
                            .AddConstructor<RaysweepChannelConditionModel>()
                            .AddAttribute("TableFile",
                                          "raysweep ns-3 table (.h5, format raysweep-ns3-table)",
                                          StringValue(""),
                                          MakeStringAccessor(&RaysweepChannelConditionModel::m_file),
                                          MakeStringChecker());
    return tid;
}

RaysweepChannelConditionModel::RaysweepChannelConditionModel() = default;

Ptr<ChannelCondition>
RaysweepChannelConditionModel::GetChannelCondition(Ptr<const MobilityModel> a, Ptr<const MobilityModel> b) const
{
    if (!m_table)
    {
        m_table = RaysweepTable::Get(m_file);
    }
    const RaysweepChannel c = m_table->Lookup(m_table->IndexOf(a), m_table->IndexOf(b), Simulator::Now(), false);
    ChannelCondition::LosConditionValue v = ChannelCondition::NLOS;
    if (c.present && c.losClass == 0)
    {
        v = ChannelCondition::LOS;
    }
    else if (c.present && c.losClass == 1)
    {
        v = ChannelCondition::NLOSv;
    }
    return CreateObject<ChannelCondition>(v);
}

int64_t
RaysweepChannelConditionModel::AssignStreams(int64_t)
{
    return 0;
}

} // namespace ns3
