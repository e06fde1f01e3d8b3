// Tests of lseg liver (being written: issue 4).
