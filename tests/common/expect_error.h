#pragma once
// Checks that a call throws a given lobe error whose message names what it should.

#include <gtest/gtest.h>

#include <exception>
#include <initializer_list>
#include <string>

namespace lobe::test {

//! Runs `f`; expects an exception of exactly type E (or derived) whose message contains every
//! one of `parts` (typically the file name and the problem).
template <class E, class F>
void expect_error(F&& f, std::initializer_list<std::string> parts)
{
    try {
        f();
        ADD_FAILURE() << "no exception thrown";
    } catch (const E& e) {
        const std::string msg = e.what();
        for (const auto& p : parts)
            EXPECT_NE(msg.find(p), std::string::npos) << "message: " << msg << "\nshould contain: " << p;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type, message: " << e.what();
    }
}

} // namespace lobe::test

//! EXPECT_LOBE_ERROR(core::IoError, read(x), "x.mha", "truncated"): expect_error with the
//! statement shown in the failure trace.
#define EXPECT_LOBE_ERROR(E, stmt, ...)                                                            \
    do {                                                                                           \
        SCOPED_TRACE(#stmt);                                                                       \
        ::lobe::test::expect_error<E>([&] { stmt; }, {__VA_ARGS__});                               \
    } while (0)
