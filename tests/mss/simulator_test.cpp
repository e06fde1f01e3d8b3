// Integrators, time step policy, blow-up detection, probes.
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

using namespace lobe;
