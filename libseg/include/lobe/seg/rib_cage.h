#pragma once
//! \file
//! \brief (being written: issue 4)

namespace lobe::seg {} // namespace lobe::seg
