#pragma once
// truth.json: what lphantom generated, as JSON (parameters, ground truth, timings).

#include "common/cli.h"
#include "lphantom/phantom.h"

#include <nlohmann/json.hpp>

#include <string>

namespace lobe::phantom {

//! The document lphantom writes as truth.json (schema: docs/phantom.md).
nlohmann::ordered_json truth_json(const PhantomParams& p, const PhantomResult& r, const std::string& command,
                                  const tools::Timings& timings);

} // namespace lobe::phantom
