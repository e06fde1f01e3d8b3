// lseg liver (being written: issue 4).
#include "lseg/commands.h"
