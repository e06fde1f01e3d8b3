// Tests of lobe/seg/rib_cage.h (being written: issue 4).
