#pragma once
//! \file
//! \brief The few exception types lobe throws. Libraries throw only these (or std::bad_alloc);
//! tools catch lobe::core::Error at the top of main and map each kind to an exit code.

#include <stdexcept>
#include <string>

namespace lobe::core {

//! Base of every lobe error; what() is a complete sentence naming the file or input at fault.
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};

//! A violated precondition or malformed input (bad geometry, wrong size, unknown type, ...).
struct InvalidInputError : Error {
    using Error::Error;
};

//! A file could not be opened, read or written, or its content is not what its format promises.
struct IoError : Error {
    using Error::Error;
};

//! A numerical method failed in a way its result cannot report (e.g. a singular system).
struct SolverError : Error {
    using Error::Error;
};

} // namespace lobe::core
