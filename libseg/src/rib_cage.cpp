#include "lobe/seg/rib_cage.h"
