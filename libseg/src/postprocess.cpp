#include "lobe/seg/postprocess.h"
