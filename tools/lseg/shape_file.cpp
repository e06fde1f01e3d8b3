// Shape memory file (being written: issue 4).
#include "lseg/shape_file.h"
