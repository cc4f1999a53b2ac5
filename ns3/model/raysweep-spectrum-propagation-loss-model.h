// ns3::RaysweepSpectrumPropagationLossModel: for spectrum-based PHYs, scales
// every band of the transmitted PSD by the table's per-band gain of the pair
// (the table band containing the band's centre frequency; the wideband gain
// where the table has no bands or the frequency lies outside them). A pair
// without a channel in the frame in force receives nothing (PSD 0).
#ifndef RAYSWEEP_SPECTRUM_PROPAGATION_LOSS_MODEL_H
#define RAYSWEEP_SPECTRUM_PROPAGATION_LOSS_MODEL_H

#include "raysweep-table.h"

#include "ns3/spectrum-propagation-loss-model.h"

namespace ns3
{

class RaysweepSpectrumPropagationLossModel : public SpectrumPropagationLossModel
{
  public:
    static TypeId GetTypeId();
    RaysweepSpectrumPropagationLossModel();

    /** The gain (dB) the model applies at frequency fHz between two nodes' mobility models, now. */
    double GainDb(double fHz, Ptr<const MobilityModel> a, Ptr<const MobilityModel> b) const;

  private:
    Ptr<SpectrumValue> DoCalcRxPowerSpectralDensity(Ptr<const SpectrumSignalParameters> params,
                                                    Ptr<const MobilityModel> a,
                                                    Ptr<const MobilityModel> b) const override;
    double BandGainDb(const RaysweepChannel& c, double fHz) const;

    std::string m_file;
    mutable Ptr<RaysweepTable> m_table;
};

} // namespace ns3

#endif
