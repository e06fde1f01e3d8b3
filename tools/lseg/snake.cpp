// lseg snake: placeholder until the CDSG snake lands (issue 3).
#include "lseg/commands.h"

namespace lobe::lseg {

Command add_snake(CLI::App& lseg)
{
    CLI::App* cmd = lseg.add_subcommand("snake", "Active-contour segmentation (not yet available)");
    return {cmd, [](const tools::Progress&, tools::RunRecord&) -> int {
                throw core::Error("lseg snake is not implemented yet");
            }};
}

} // namespace lobe::lseg
