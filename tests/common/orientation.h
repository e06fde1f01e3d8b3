#pragma once
// How the orientation tests store an axial volume in another plane.

#include "lobe/core/image3d.h"

namespace lobe::test {

//! An axial grid stored as a coronal stack, as a coronal series is: rows along x, columns to the
//! feet (the axial slices reversed), slices to the back (core::reorder_axes with it).
inline core::AxisOrder coronal_storage()
{
    core::AxisOrder order;
    order.from = {0, 2, 1};
    order.flip = {false, true, false};
    return order;
}

} // namespace lobe::test
