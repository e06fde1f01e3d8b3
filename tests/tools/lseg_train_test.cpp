// Tests of lseg train (being written: issue 4).
