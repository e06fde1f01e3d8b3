// lseg eval: placeholder, replaced by the metrics work.
#include "lseg/commands.h"

namespace lobe::lseg {

Command add_eval(CLI::App& lseg)
{
    CLI::App* cmd = lseg.add_subcommand("eval", "Compare a segmentation with a reference (not yet available)");
    return {cmd, [](const tools::Progress&, tools::RunRecord&) -> int {
                throw core::Error("lseg eval is not implemented yet");
            }};
}

} // namespace lobe::lseg
