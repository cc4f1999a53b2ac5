#include "raysweep-table.h"

#include "ns3/fatal-error.h"
#include "ns3/log.h"
#include "ns3/node.h"
#include "ns3/simulator.h"

#include "meshkit/errors.hpp"

#include <cmath>
#include <limits>

namespace ns3
{

NS_LOG_COMPONENT_DEFINE("RaysweepTable");
NS_OBJECT_ENSURE_REGISTERED(RaysweepTable);

TypeId
RaysweepTable::GetTypeId()
{
    static TypeId tid = TypeId("ns3::RaysweepTable").SetParent<Object>().SetGroupName("Raysweep");
    return tid;
}

Ptr<RaysweepTable>
RaysweepTable::Get(const std::string& file)
{
    static std::map<std::string, Ptr<RaysweepTable>> loaded;
    if (file.empty())
    {
        NS_FATAL_ERROR("Raysweep: no table file given (attribute TableFile)");
    }
    auto it = loaded.find(file);
    if (it != loaded.end())
    {
        return it->second;
    }
    Ptr<RaysweepTable> t = CreateObject<RaysweepTable>();
    try
    {
        t->m_table = raysweep::generators::Ns3Table::load(file);
    }
    catch (const std::exception& e)
    {
        NS_FATAL_ERROR("Raysweep table " << e.what());
    }
    NS_LOG_INFO("loaded " << file << ": " << t->m_table.frames() << " frames, " << t->m_table.pair_count()
                          << " pair-frames, " << t->m_table.memory_bytes() << " bytes in memory");
    loaded.emplace(file, t);
    return t;
}

void
RaysweepTable::Bind(uint32_t nodeId, uint32_t index)
{
    if (index >= m_table.node_count())
    {
        NS_FATAL_ERROR("Raysweep table " << File() << ": cannot bind ns-3 node " << nodeId << " to table node "
                                         << index << ": the table has " << m_table.node_count() << " nodes");
    }
    m_binding[nodeId] = index;
}

uint32_t
RaysweepTable::IndexOf(const std::string& name) const
{
    const auto& ids = m_table.node_ids();
    for (uint32_t i = 0; i < ids.size(); ++i)
    {
        if (ids[i] == name)
        {
            return i;
        }
    }
    NS_FATAL_ERROR("Raysweep table " << File() << ": no node '" << name << "'");
    return 0;
}

uint32_t
RaysweepTable::IndexOf(Ptr<const MobilityModel> m) const
{
    Ptr<Node> node = m ? m->GetObject<Node>() : nullptr;
    if (!node)
    {
        NS_FATAL_ERROR("Raysweep table " << File()
                                         << ": a mobility model without a node (aggregate it to a node bound "
                                            "by RaysweepHelper)");
    }
    auto it = m_binding.find(node->GetId());
    if (it == m_binding.end())
    {
        NS_FATAL_ERROR("Raysweep table " << File() << ": ns-3 node " << node->GetId()
                                         << " is not bound to a table node (RaysweepHelper::Bind / CreateNodes)");
    }
    return it->second;
}

std::size_t
RaysweepTable::FrameAt(Time t) const
{
    const auto f = m_table.frame_at(t.GetSeconds());
    if (!f)
    {
        const std::size_t n = m_table.frames();
        NS_FATAL_ERROR("Raysweep table " << File() << ": time " << t.GetSeconds() << " s is outside the table ("
                                         << (n ? m_table.time(0) : 0.0) << " s .. "
                                         << (n ? m_table.time(n - 1) + m_table.frame_step() : 0.0) << " s)");
    }
    return *f;
}

RaysweepChannel
RaysweepTable::Lookup(uint32_t a, uint32_t b, Time t, bool interpolate) const
{
    RaysweepChannel c;
    c.frame = FrameAt(t);
    const auto row = m_table.pair_row(c.frame, a, b);
    if (!row)
    {
        return c; // a node is absent from the frame: no channel
    }
    c.present = true;
    c.row = *row;
    c.gainDb = m_table.gain_db(*row);
    c.losClass = m_table.los_class(*row);
    if (interpolate && c.frame + 1 < m_table.frames() && std::isfinite(c.gainDb))
    {
        const auto next = m_table.pair_row(c.frame + 1, a, b);
        if (next && std::isfinite(m_table.gain_db(*next)))
        {
            const double t0 = m_table.time(c.frame), t1 = m_table.time(c.frame + 1);
            const double w = (t.GetSeconds() - t0) / (t1 - t0);
            c.gainDb += w * (m_table.gain_db(*next) - c.gainDb);
        }
    }
    return c;
}

} // namespace ns3
