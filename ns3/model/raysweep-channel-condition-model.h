// ns3::RaysweepChannelConditionModel: LOS / NLOSv / NLOS of a pair from a
// raysweep ns-3 table at the frame in force, so ns-3's own 3GPP models can run
// with ray-traced LoS states. A pair without a channel in the frame (a node not
// on the road) is NLOS.
#ifndef RAYSWEEP_CHANNEL_CONDITION_MODEL_H
#define RAYSWEEP_CHANNEL_CONDITION_MODEL_H

#include "raysweep-table.h"

#include "ns3/channel-condition-model.h"

namespace ns3
{

class RaysweepChannelConditionModel : public ChannelConditionModel
{
  public:
    static TypeId GetTypeId();
    RaysweepChannelConditionModel();

    Ptr<ChannelCondition> GetChannelCondition(Ptr<const MobilityModel> a,
                                              Ptr<const MobilityModel> b) const override;
    int64_t AssignStreams(int64_t stream) override;

  private:
    std::string m_file;
    mutable Ptr<RaysweepTable> m_table;
};

} // namespace ns3

#endif
