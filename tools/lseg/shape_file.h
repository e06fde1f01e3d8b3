#pragma once
// Reading and writing the shape memory file of lseg train (being written: issue 4).
