// ns3::RaysweepMobilityModel: a node that follows its table node's states.
// Position: the table's position at frame times, linear between consecutive
// frames in which the node is present, held before its first and after its last
// frame. Velocity: the table's velocity of the latest frame at or before now
// (the first one before it), zero when the node never appears.
#ifndef RAYSWEEP_MOBILITY_MODEL_H
#define RAYSWEEP_MOBILITY_MODEL_H

#include "raysweep-table.h"

#include "ns3/mobility-model.h"

#include <vector>

namespace ns3
{

class RaysweepMobilityModel : public MobilityModel
{
  public:
    static TypeId GetTypeId();
    RaysweepMobilityModel();

    /** Follows node `index` of `table`. */
    void Follow(Ptr<RaysweepTable> table, uint32_t index);
    uint32_t GetTableIndex() const { return m_index; }

  private:
    Vector DoGetPosition() const override;
    void DoSetPosition(const Vector& position) override;
    Vector DoGetVelocity() const override;
    std::size_t Before(double t) const; // last state with time <= t (0 when none)

    Ptr<RaysweepTable> m_table;
    uint32_t m_index = 0;
    std::vector<double> m_time;    //!< frame times at which the node is present
    std::vector<std::size_t> m_frame;
    std::vector<raysweep::generators::NodeState> m_state;
};

} // namespace ns3

#endif
