#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include "support/support.h"

// doctest's own main, then: a passing run deletes the scratch folders it
// made (a full suite writes ~0.5 GB of sequences). A failing run keeps them
// for the post-mortem, and so does SCOPETRACK_KEEP_TEST_TMP=1.
int main(int argc, char** argv) {
  doctest::Context context(argc, argv);
  const int result = context.run();
  if (result == 0 && !context.shouldExit()) st::test::remove_scratch_dirs();
  return result;
}
