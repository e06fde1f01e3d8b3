// Tests of lobe/seg/liver.h (being written: issue 4).
