#pragma once
//! \file
//! \brief Version of the lobe::mss library, as built.

namespace lobe::mss {

//! The lobe version this library was built from ("major.minor.patch").
const char* version();

} // namespace lobe::mss
