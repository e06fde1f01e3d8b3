#include "lobe/seg/start_slice.h"
