#include "lobe/mss/version.h"

namespace lobe::mss {

const char* version() { return LOBE_VERSION_STRING; }

} // namespace lobe::mss
