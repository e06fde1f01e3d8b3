// lseg: segmentation from the command line. Each subcommand lives in its own file.
#include "common/cli.h"
#include "lseg/commands.h"

#include <vector>

using namespace lobe;

int main(int argc, char** argv)
{
    CLI::App app{"lseg: segment CT/MRI volumes (active contours: CDSG, GGVF, GAC; the liver, its vessels and "
                 "tumours) and evaluate segmentations (Dice, SLIVER07 measures and score)",
                 "lseg"};
    bool quiet = false;
    tools::add_common_options(app, quiet);
    app.require_subcommand(1);
    app.fallthrough(); // --quiet may follow the subcommand (subcommands inherit this)
    const std::vector<lseg::Command> commands = {lseg::add_snake(app), lseg::add_eval(app),    lseg::add_train(app),
                                                 lseg::add_liver(app), lseg::add_vessels(app), lseg::add_tumours(app),
                                                 lseg::add_all(app),   lseg::add_bias(app)};

    tools::RunRecord record(app, argc, argv);
    return tools::run_tool(app, argc, argv, [&] {
        const tools::Progress progress("lseg", quiet);
        for (const auto& c : commands)
            if (c.app->parsed())
                return c.run(progress, record);
        return static_cast<int>(tools::kExitUsage);
    });
}
