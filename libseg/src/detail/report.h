#pragma once
// Parameter checks and number formatting shared by the vessel and tumour pipelines' messages.
// Private to libseg (never installed).

#include "lobe/core/errors.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <string>

namespace lobe::seg::detail {

//! v with `digits` decimals, for messages.
inline std::string fixed(double v, int digits = 1)
{
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << v;
    return s.str();
}

//! Throws InvalidInputError "<where>: <name> must be finite and >= 0" unless v is.
inline void require_nonnegative(double v, const char* where, const char* name)
{
    if (!(v >= 0) || !std::isfinite(v))
        throw core::InvalidInputError(std::string(where) + ": " + name + " must be finite and >= 0");
}

} // namespace lobe::seg::detail
