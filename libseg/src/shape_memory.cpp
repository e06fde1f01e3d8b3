#include "lobe/seg/shape_memory.h"
