#include "raysweep-helper.h"

#include "ns3/boolean.h"
#include "ns3/node.h"
#include "ns3/string.h"

namespace ns3
{

RaysweepHelper::RaysweepHelper(const std::string& tableFile)
    : m_file(tableFile),
      m_table(RaysweepTable::Get(tableFile))
{
}

void
RaysweepHelper::Install(Ptr<Node> node, uint32_t index)
{
    m_table->Bind(node->GetId(), index);
    Ptr<RaysweepMobilityModel> m = CreateObject<RaysweepMobilityModel>();
    m->Follow(m_table, index);
    node->AggregateObject(m);
}

NodeContainer
RaysweepHelper::CreateNodes()
{
    NodeContainer nodes;
    nodes.Create(static_cast<uint32_t>(m_table->Data().node_count()));
    for (uint32_t i = 0; i < nodes.GetN(); ++i)
    {
        Install(nodes.Get(i), i);
    }
    return nodes;
}

Ptr<RaysweepPropagationLossModel>
RaysweepHelper::CreatePropagationLossModel(bool interpolation) const
{
    Ptr<RaysweepPropagationLossModel> m = CreateObject<RaysweepPropagationLossModel>();
    m->SetAttribute("TableFile", StringValue(m_file));
    m->SetAttribute("Interpolation", BooleanValue(interpolation));
    return m;
}

Ptr<RaysweepChannelConditionModel>
RaysweepHelper::CreateChannelConditionModel() const
{
    Ptr<RaysweepChannelConditionModel> m = CreateObject<RaysweepChannelConditionModel>();
    m->SetAttribute("TableFile", StringValue(m_file));
    return m;
}

Ptr<RaysweepSpectrumPropagationLossModel>
RaysweepHelper::CreateSpectrumPropagationLossModel() const
{
    Ptr<RaysweepSpectrumPropagationLossModel> m = CreateObject<RaysweepSpectrumPropagationLossModel>();
    m->SetAttribute("TableFile", StringValue(m_file));
    return m;
}

std::vector<std::string>
RaysweepCommandLineArgs(int argc, char* argv[])
{
    std::vector<std::string> args;
    for (int i = 0; i < argc; ++i)
    {
        std::string a = argv[i];
        if (i > 0 && a.rfind("--", 0) == 0 && a.find('=') == std::string::npos && i + 1 < argc &&
            std::string(argv[i + 1]).rfind("--", 0) != 0)
        {
            a += "=" + std::string(argv[++i]);
        }
        args.push_back(a);
    }
    return args;
}

} // namespace ns3
