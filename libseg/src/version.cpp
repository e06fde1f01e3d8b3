#include "lobe/seg/version.h"

namespace lobe::seg {

const char* version() { return LOBE_VERSION_STRING; }

} // namespace lobe::seg
