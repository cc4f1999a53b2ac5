#include "raysweep-spectrum-propagation-loss-model.h"

#include "ns3/simulator.h"
#include "ns3/spectrum-signal-parameters.h"
#include "ns3/string.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ns3
{

NS_OBJECT_ENSURE_REGISTERED(RaysweepSpectrumPropagationLossModel);

TypeId
RaysweepSpectrumPropagationLossModel::GetTypeId()
{
    static TypeId tid = TypeId("ns3::RaysweepSpectrumPropagationLossModel")
                            .SetParent<SpectrumPropagationLossModel>()
                            .SetGroupName("Raysweep")
                            .AddConstructor<RaysweepSpectrumPropagationLossModel>()
                            .AddAttribute("TableFile",
                                          "raysweep ns-3 table (.h5, format raysweep-ns3-table)",
                                          StringValue(""),
                                          MakeStringAccessor(&RaysweepSpectrumPropagationLossModel::m_file),
                                          MakeStringChecker());
    return tid;
}

RaysweepSpectrumPropagationLossModel::RaysweepSpectrumPropagationLossModel() = default;

double
RaysweepSpectrumPropagationLossModel::BandGainDb(const RaysweepChannel& c, double fHz) const
{
    if (!c.present)
    {
        return -std::numeric_limits<double>::infinity();
    }
    const auto& bands = m_table->Data().bands();
    const float* g = m_table->Data().band_gain_db(c.row);
    if (!g || bands.count() == 0)
    {
        return c.gainDb;
    }
    // The band whose centre is nearest, when f lies within half a band width of it.
    const auto& centers = bands.center_hz;
    auto it = std::lower_bound(centers.begin(), centers.end(), fHz);
    std::size_t k = it == centers.end() ? centers.size() - 1 : static_cast<std::size_t>(it - centers.begin());
    if (k > 0 && std::abs(centers[k - 1] - fHz) < std::abs(centers[k] - fHz))
    {
        --k;
    }
    if (std::abs(centers[k] - fHz) > 0.5 * bands.band_width_hz)
    {
        return c.gainDb;
    }
    return g[k];
}

double
RaysweepSpectrumPropagationLossModel::GainDb(double fHz, Ptr<const MobilityModel> a, Ptr<const MobilityModel> b) const
{
    if (!m_table)
    {
        m_table = RaysweepTable::Get(m_file);
    }
    const RaysweepChannel c = m_table->Lookup(m_table->IndexOf(a), m_table->IndexOf(b), Simulator::Now(), false);
    return BandGainDb(c, fHz);
}

Ptr<SpectrumValue>
RaysweepSpectrumPropagationLossModel::DoCalcRxPowerSpectralDensity(Ptr<const SpectrumSignalParameters> params,
                                                                   Ptr<const MobilityModel> a,
                                                                   Ptr<const MobilityModel> b) const
{
    if (!m_table)
    {
        m_table = RaysweepTable::Get(m_file);
    }
    const RaysweepChannel c = m_table->Lookup(m_table->IndexOf(a), m_table->IndexOf(b), Simulator::Now(), false);
    Ptr<SpectrumValue> rx = Copy<SpectrumValue>(params->psd);
    auto band = rx->ConstBandsBegin();
    for (auto v = rx->ValuesBegin(); v != rx->ValuesEnd(); ++v, ++band)
    {
        const double g = BandGainDb(c, band->fc);
        *v *= std::isfinite(g) ? std::pow(10.0, g / 10.0) : 0.0;
    }
    return rx;
}

} // namespace ns3
