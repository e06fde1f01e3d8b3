#include "lobe/mesh/version.h"

namespace lobe::mesh {

const char* version() { return LOBE_VERSION_STRING; }

} // namespace lobe::mesh
