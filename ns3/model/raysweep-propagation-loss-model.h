// ns3::RaysweepPropagationLossModel: rx power = tx power + the pair's wideband
// gain from a raysweep ns-3 table at the frame in force (largest frame time <=
// now; sample and hold, or linear in dB with Interpolation = true).
#ifndef RAYSWEEP_PROPAGATION_LOSS_MODEL_H
#define RAYSWEEP_PROPAGATION_LOSS_MODEL_H

#include "raysweep-table.h"

#include "ns3/propagation-loss-model.h"
#include "ns3/traced-callback.h"

namespace ns3
{

class RaysweepPropagationLossModel : public PropagationLossModel
{
  public:
    static TypeId GetTypeId();
    RaysweepPropagationLossModel();

    /** The table (loaded from TableFile on first use). */
    Ptr<RaysweepTable> GetTable() const;

    /**
     * Fired on every evaluation: tx and rx table nodes, tx and rx power (dBm; -inf
     * when the pair has no channel in the frame in force), LoS class (255: none).
     */
    typedef void (*RxPowerTracedCallback)(uint32_t tx, uint32_t rx, double txPowerDbm, double rxPowerDbm,
                                          uint8_t losClass);

  private:
    double DoCalcRxPower(double txPowerDbm, Ptr<MobilityModel> a, Ptr<MobilityModel> b) const override;
    int64_t DoAssignStreams(int64_t stream) override;

    std::string m_file;
    bool m_interpolate = false;
    mutable Ptr<RaysweepTable> m_table;
    TracedCallback<uint32_t, uint32_t, double, double, uint8_t> m_rxPowerTrace;
};

} // namespace ns3

#endif
