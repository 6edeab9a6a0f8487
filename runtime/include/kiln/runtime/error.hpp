#pragma once

#include <stdexcept>
#include <string>

namespace kiln {

// A blob that cannot be opened or verified. what() is one line naming the file, the section
// (when there is one) and what is wrong.
class BlobError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace kiln
