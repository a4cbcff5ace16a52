#pragma once
// Errors at the API boundary. Bad input (a file, an option) is an InputError whose message is one sentence
// naming the file, line, element or channel; the CLI turns it into exit code 2. Numerical outcomes are never
// exceptions: they are statuses and diagnostics inside results.

#include <stdexcept>
#include <string>

namespace feedid {

/// Bad user input: a malformed file, an unknown unit, a missing channel, an invalid option.
class InputError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// The analysis could not be carried out on valid input (for example, the data cannot identify the model).
/// The CLI turns it into exit code 1.
class AnalysisError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

}  // namespace feedid
