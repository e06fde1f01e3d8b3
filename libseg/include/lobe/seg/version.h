#pragma once
//! \file
//! \brief Version of the lobe::seg library, as built.

namespace lobe::seg {

//! The lobe version this library was built from ("major.minor.patch").
const char* version();

} // namespace lobe::seg
