// Tests of lobe/seg/postprocess.h (being written: issue 4).
