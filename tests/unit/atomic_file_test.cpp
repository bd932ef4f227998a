#include "pm/base/atomic_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "pm/base/error.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

TEST(AtomicFile, CommitRenamesAndKeepsExtension) {
  const std::string dir = test::temp_dir();
  const std::string target = dir + "/out.nii.gz";
  {
    AtomicFile f(target);
    EXPECT_EQ(file_extension(f.temp_path()), ".nii.gz");
    EXPECT_EQ(fs::path(f.temp_path()).parent_path(), fs::path(dir));
    std::ofstream(f.temp_path()) << "x";
    EXPECT_FALSE(fs::exists(target));
    f.commit();
  }
  EXPECT_TRUE(fs::exists(target));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(AtomicFile, FailureLeavesNothing) {
  const std::string dir = test::temp_dir();
  EXPECT_THROW(write_atomically(dir + "/a.ply",
                                [](const std::string& tmp) {
                                  std::ofstream(tmp) << "partial";
                                  throw IoError("disk full");
                                }),
               IoError);
  EXPECT_TRUE(fs::is_empty(dir));
  EXPECT_THROW(AtomicFile(dir + "/missing/x.ply"), IoError);
}

TEST(AtomicFile, Extensions) {
  EXPECT_EQ(file_extension("a/b.NRRD"), ".nrrd");
  EXPECT_EQ(file_extension("x.nii.gz"), ".nii.gz");
  EXPECT_EQ(file_extension("x.inr.gz"), ".inr.gz");
  EXPECT_EQ(file_extension("noext"), "");
  EXPECT_EQ(file_extension(".hidden"), "");
  EXPECT_THROW(require_readable("/nonexistent/file"), IoError);
}

}  // namespace
}  // namespace pm
