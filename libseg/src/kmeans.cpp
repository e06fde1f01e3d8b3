#include "lobe/seg/kmeans.h"
