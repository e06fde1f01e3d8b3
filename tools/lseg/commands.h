#pragma once
// lseg's subcommands. Each file adds its subcommand to the app and returns how to run it;
// main.cpp runs the one the user chose.

#include "common/cli.h"

#include <functional>

namespace lobe::lseg {

struct Command {
    CLI::App* app = nullptr; //!< the subcommand
    std::function<int(const tools::Progress&, tools::RunRecord&)> run;
};

Command add_eval(CLI::App& lseg); //!< lseg eval SEG REF: Dice, the SLIVER07 measures and score
Command add_snake(CLI::App& lseg); //!< lseg snake IMAGE: CDSG / GGVF / GAC active contours
Command add_train(CLI::App& lseg); //!< lseg train --image --labels ... -o: the shape memory
Command add_liver(CLI::App& lseg); //!< lseg liver IMAGE -o OUT.h5: automatic liver segmentation
Command add_vessels(CLI::App& lseg); //!< lseg vessels IMAGE -o OUT.h5: hepatic vessel trees
Command add_tumours(CLI::App& lseg); //!< lseg tumours IMAGE -o OUT.h5: liver tumours
Command add_bias(CLI::App& lseg);    //!< lseg bias IMAGE -o OUT.h5: MR shading corrected, and the field
Command add_all(CLI::App& lseg);     //!< lseg all IMAGE -o OUT.h5: liver, vessels, tumours in one label volume

} // namespace lobe::lseg
