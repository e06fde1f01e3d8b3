// Tests of lobe/seg/shape_memory.h (being written: issue 4).
