#include "raysweep-mobility-model.h"

#include "ns3/fatal-error.h"
#include "ns3/simulator.h"

#include <algorithm>

namespace ns3
{

NS_OBJECT_ENSURE_REGISTERED(RaysweepMobilityModel);

TypeId
RaysweepMobilityModel::GetTypeId()
{
    static TypeId tid = TypeId("ns3::RaysweepMobilityModel")
                            .SetParent<MobilityModel>()
                            .SetGroupName("Raysweep")
                            .AddConstructor<RaysweepMobilityModel>();
    return tid;
}

RaysweepMobilityModel::RaysweepMobilityModel() = default;

void
RaysweepMobilityModel::Follow(Ptr<RaysweepTable> table, uint32_t index)
{
    const auto& t = table->Data();
    if (index >= t.node_count())
    {
        NS_FATAL_ERROR("Raysweep table " << table->File() << ": no table node " << index);
    }
    m_table = table;
    m_index = index;
    m_time.clear();
    m_frame.clear();
    m_state.clear();
    for (std::size_t f = 0; f < t.frames(); ++f)
    {
        if (const auto* s = t.state(f, index))
        {
            m_time.push_back(t.time(f));
            m_frame.push_back(f);
            m_state.push_back(*s);
        }
    }
}

std::size_t
RaysweepMobilityModel::Before(double t) const
{
    const auto it = std::upper_bound(m_time.begin(), m_time.end(), t);
    return it == m_time.begin() ? 0 : static_cast<std::size_t>(it - m_time.begin() - 1);
}

Vector
RaysweepMobilityModel::DoGetPosition() const
{
    if (m_state.empty())
    {
        return Vector(0, 0, 0);
    }
    const double t = Simulator::Now().GetSeconds();
    const std::size_t i = Before(t);
    const auto& s = m_state[i];
    if (t <= m_time[i] || i + 1 >= m_state.size() || m_frame[i + 1] != m_frame[i] + 1)
    {
        return Vector(s.x, s.y, s.z);
    }
    const auto& n = m_state[i + 1];
    const double w = (t - m_time[i]) / (m_time[i + 1] - m_time[i]);
    return Vector(s.x + w * (n.x - s.x), s.y + w * (n.y - s.y), s.z + w * (n.z - s.z));
}

void
RaysweepMobilityModel::DoSetPosition(const Vector&)
{
    NS_FATAL_ERROR("RaysweepMobilityModel: positions come from the table " << (m_table ? m_table->File() : "")
                                                                           << " and cannot be set");
}

Vector
RaysweepMobilityModel::DoGetVelocity() const
{
    if (m_state.empty())
    {
        return Vector(0, 0, 0);
    }
    const auto& s = m_state[Before(Simulator::Now().GetSeconds())];
    return Vector(s.vx, s.vy, s.vz);
}

} // namespace ns3
