// Tests of lobe/seg/start_slice.h (being written: issue 4).
