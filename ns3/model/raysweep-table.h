// A raysweep ns-3 lookup table (format raysweep-ns3-table, schemas/) loaded once
// per file and shared by every Raysweep model and mobility model that names it,
// together with the binding of ns-3 nodes to the table's nodes.
#ifndef RAYSWEEP_TABLE_H
#define RAYSWEEP_TABLE_H

#include "ns3/mobility-model.h"
#include "ns3/nstime.h"
#include "ns3/object.h"

#include "generators/ns3_table/ns3_table.hpp"

#include <cstdint>
#include <map>
#include <string>

namespace ns3
{

/**
 * The channel of one (tx, rx) pair at one time, as the table gives it.
 */
struct RaysweepChannel
{
    bool present = false;  //!< the table has a channel for the pair at this time (both nodes on the road)
    double gainDb = 0;     //!< wideband power gain (-inf: no path); meaningful when present
    uint8_t losClass = 0;  //!< 0 LOS, 1 NLOSv, 2 NLOS
    std::size_t row = 0;   //!< the table row of the frame in force (per-band gains)
    std::size_t frame = 0; //!< the frame in force
};

class RaysweepTable : public Object
{
  public:
    static TypeId GetTypeId();

    /**
     * The table of a file, loaded on first use. A missing, unreadable or corrupt
     * file is a fatal error naming the file and the element.
     */
    static Ptr<RaysweepTable> Get(const std::string& file);

    const raysweep::generators::Ns3Table& Data() const { return m_table; }
    const std::string& File() const { return m_table.path(); }

    /** Binds an ns-3 node to table node `index` (fatal when index is not a table node). */
    void Bind(uint32_t nodeId, uint32_t index);
    /** The table index of node `name` (a SUMO vehicle id); fatal when there is none. */
    uint32_t IndexOf(const std::string& name) const;
    /** The table node of a mobility model's node; fatal when it has no node or the node is not bound. */
    uint32_t IndexOf(Ptr<const MobilityModel> m) const;

    /** The frame in force at t (largest frame time <= t); fatal outside the table's time span. */
    std::size_t FrameAt(Time t) const;

    /**
     * The channel between table nodes a and b at time t. With interpolate, the
     * gain is linear in dB between the frame in force and the next one when both
     * have the pair with finite gains; otherwise sample and hold.
     */
    RaysweepChannel Lookup(uint32_t a, uint32_t b, Time t, bool interpolate) const;

  private:
    raysweep::generators::Ns3Table m_table;
    std::map<uint32_t, uint32_t> m_binding; //!< ns-3 node id -> table node
};

} // namespace ns3

#endif
