#include "lobe/seg/liver.h"
