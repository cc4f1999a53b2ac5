// RaysweepHelper: nodes for a raysweep ns-3 table's nodes, mobility that
// follows the table, and the Raysweep models bound to the same table.
//
//   RaysweepHelper rs("table.h5");
//   NodeContainer nodes = rs.CreateNodes();        // node i <-> table node i
//   channel.SetPropagationLoss(rs.CreatePropagationLossModel());
#ifndef RAYSWEEP_HELPER_H
#define RAYSWEEP_HELPER_H

#include "ns3/node-container.h"
#include "ns3/raysweep-channel-condition-model.h"
#include "ns3/raysweep-mobility-model.h"
#include "ns3/raysweep-propagation-loss-model.h"
#include "ns3/raysweep-spectrum-propagation-loss-model.h"
#include "ns3/raysweep-table.h"

#include <string>
#include <vector>

namespace ns3
{

class RaysweepHelper
{
  public:
    /** Loads the table (fatal error naming the file when it cannot). */
    explicit RaysweepHelper(const std::string& tableFile);

    Ptr<RaysweepTable> GetTable() const { return m_table; }

    /** One node per table node, in table order, each with a RaysweepMobilityModel, bound. */
    NodeContainer CreateNodes();
    /** Binds an existing node to table node `index` and gives it a RaysweepMobilityModel. */
    void Install(Ptr<Node> node, uint32_t index);

    Ptr<RaysweepPropagationLossModel> CreatePropagationLossModel(bool interpolation = false) const;
    Ptr<RaysweepChannelConditionModel> CreateChannelConditionModel() const;
    Ptr<RaysweepSpectrumPropagationLossModel> CreateSpectrumPropagationLossModel() const;

  private:
    std::string m_file;
    Ptr<RaysweepTable> m_table;
};

/**
 * The command line with "--name value" pairs joined into ns-3's "--name=value"
 * (argv[0] first), so the examples take both spellings.
 */
std::vector<std::string> RaysweepCommandLineArgs(int argc, char* argv[]);

} // namespace ns3

#endif
