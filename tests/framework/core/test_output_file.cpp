// Checked output files: a failed write names the file and the reason, a CSV keeps whole
// lines, an atomic replace leaves the old file when it fails.
#include <catch2/catch.hpp>

#include "core/output_file.hpp"
#include "test_support.hpp"

using namespace pinsim;
using Catch::Matchers::Contains;
namespace fs = std::filesystem;

TEST_CASE("output file: whole lines are appended and counted") {
  const fs::path dir = test::temp_dir("linefile");
  LineFile f(dir / "a.csv", "a,b\n");
  f.append("1,2\n3,4\n");
  CHECK(f.size() == 12);
  f.close();
  f.close();  // once closed, nothing more
  CHECK(test::read_file(dir / "a.csv") == "a,b\n1,2\n3,4\n");
}

TEST_CASE("output file: a write to a full device is an error naming the file") {
  // /dev/full refuses every write with ENOSPC; a device cannot be cut back either.
  REQUIRE_THROWS_MATCHES(
      LineFile("/dev/full", "a,b\n"), OutputError,
      Catch::Matchers::Message("/dev/full: cannot write (No space left on device); could not cut "
                               "it back to its last whole line either (Invalid argument)"));
}

TEST_CASE("output file: an atomic replace that fails leaves the old file and no temporary") {
  const fs::path dir = test::temp_dir("atomic");
  write_file_atomically(dir / "s.json", "{\"a\": 1}\n");
  CHECK(test::read_file(dir / "s.json") == "{\"a\": 1}\n");
  write_file_atomically(dir / "s.json", "{\"a\": 2}\n");
  CHECK(test::read_file(dir / "s.json") == "{\"a\": 2}\n");
  // A folder in the way: the rename fails.
  fs::create_directories(dir / "d.json");
  REQUIRE_THROWS_MATCHES(
      write_file_atomically(dir / "d.json", "x"), OutputError,
      Catch::Matchers::Message((dir / "d.json").string() + ": cannot write (Is a directory)"));
  CHECK(fs::is_directory(dir / "d.json"));
  // No folder at all.
  REQUIRE_THROWS_MATCHES(write_file_atomically(dir / "no" / "s.json", "x"), OutputError,
                         Catch::Matchers::Message((dir / "no" / "s.json").string() +
                                                  ": cannot write (No such file or directory)"));
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    CHECK_THAT(e.path().filename().string(), !Contains(".tmp."));
    ++files;
  }
  CHECK(files == 2);
}
