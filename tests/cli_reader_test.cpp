// The command line's text reader, in process: blocks of whole lines, line
// numbers across blocks, a file that changes while it is read, a line longer
// than a block, messages about bytes that are not printable.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli/command_line.hpp"
#include "cli/number_table.hpp"

namespace {

namespace fs = std::filesystem;
using pwcontact::cli::CommandError;
using pwcontact::cli::ExitStatus;
using pwcontact::cli::NumberColumns;
using pwcontact::cli::TextInput;

class Reader : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::path(::testing::TempDir()) / "pwcontact_reader.XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    directory_ = pattern;
  }
  void TearDown() override { fs::remove_all(directory_); }
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = directory_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }

 private:
  fs::path directory_;
};

// n lines "k k+0.5" (two numbers, the second padded with zeros), ~40 MB for a million.
std::string numbered_lines(std::size_t n) {
  std::string text;
  char line[64];
  for (std::size_t k = 0; k < n; ++k) {
    const int length = std::snprintf(line, sizeof line, "%zu %zu.500000000000000000000000\n", k, k);
    text.append(line, std::size_t(length));
  }
  return text;
}

TEST_F(Reader, BlocksKeepEveryRecordInOrderAndTheLineNumbersCountAcross) {
  // ~45 MB: three blocks of 16 MiB.
  const std::string path = write("lines.txt", numbered_lines(1200000));
  TextInput input(path);
  std::size_t blocks = 0, records = 0;
  bool in_order = true;
  pwcontact::cli::for_each_number_block(input, 2, 2, true, [&](NumberColumns& block) {
    ++blocks;
    for (std::size_t i = 0; i < block.records(); ++i, ++records) {
      in_order = in_order && block.columns[0][i] == double(records) &&
                 block.columns[1][i] == double(records) + 0.5 && block.line[i] == records + 1;
    }
  });
  EXPECT_GE(blocks, 3u);
  EXPECT_EQ(records, 1200000u);
  EXPECT_TRUE(in_order);
}

// Reading the file as a table of two numbers per line stops with a usage
// error whose message holds `text`.
void expect_malformed(const std::string& path, const std::string& text) {
  TextInput input(path);
  try {
    pwcontact::cli::for_each_number_block(input, 2, 2, false, [](NumberColumns&) {});
    ADD_FAILURE() << "no error";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.exit_status(), ExitStatus::usage_error);
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

TEST_F(Reader, AMalformedLineInALaterBlockIsNamedByItsLineInTheInput) {
  std::string text = numbered_lines(1000000);
  text += "1 2 3\n";
  const std::string path = write("bad.txt", text);
  expect_malformed(path, "bad.txt:1000001: expected 2 numbers, found 3");
}

TEST_F(Reader, AFileThatShrinksWhileItIsReadIsAnInputError) {
  // Was (with the file mapped into memory): SIGBUS and no message.
  const std::string path = write("shrinking.txt", numbered_lines(1000000));
  TextInput input(path);
  try {
    input.read_lines([&](std::string_view) { truncate(path.c_str(), 1000); });
    ADD_FAILURE() << "no error";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.exit_status(), ExitStatus::io_error);
    EXPECT_NE(std::string(e.what()).find("changed while it was read"), std::string::npos)
        << e.what();
  }
}

TEST_F(Reader, ALineLongerThanABlockIsMalformedWithItsNumber) {
  std::string text = "1 2\n3 4\n";
  text += std::string(TextInput::block_bytes + 10, '0');
  text += "\n";
  const std::string path = write("long.txt", text);
  expect_malformed(path, "long.txt:3: line longer than 16 MiB");
}

}  // namespace
