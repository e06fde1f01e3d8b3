#pragma once
//! \file
//! \brief Version of the lobe::mesh library, as built.

namespace lobe::mesh {

//! The lobe version this library was built from ("major.minor.patch").
const char* version();

} // namespace lobe::mesh
