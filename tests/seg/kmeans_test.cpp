// Tests of lobe/seg/kmeans.h (being written: issue 4).
