// The command line end to end: the built `pwcontact` binary is run in a
// fresh temporary directory per test, its files, standard output, standard
// error and exit status checked.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "pwcontact/pwcontact.hpp"

namespace {

namespace fs = std::filesystem;
using pwcontact::Status;

// What a run of the binary did.
struct Outcome {
  int exit_status = -1;
  std::string out, err;
};

// One output line: mu2 lambda status.
struct Result {
  double mu2, lambda;
  int status;
};

std::string quoted(const std::string& text) { return "'" + text + "'"; }

std::string number_text(double x) {
  char text[32];
  return std::string(
      text, std::to_chars(text, text + sizeof text, x, std::chars_format::general, 17).ptr);
}

// A sphere of radius a as the 6 numbers of Q = a^2 I.
std::string sphere_text(double a) {
  const std::string a2 = number_text(a * a);
  return a2 + " 0 0 " + a2 + " 0 " + a2;
}

const std::string unit_sphere = sphere_text(1);

// The pairs as input lines of `pwcontact contact`.
std::string pairs_text(const pwcontact::PairBatch<double>& pairs) {
  std::string text;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    double r12[3], q1[6], q2[6];
    pairs.get(i, r12, q1, q2);
    std::string line;
    for (double x : r12) line += number_text(x) + " ";
    for (double x : q1) line += number_text(x) + " ";
    for (double x : q2) line += number_text(x) + " ";
    line.back() = '\n';
    text += line;
  }
  return text;
}

std::vector<Result> parse_results(const std::string& text) {
  std::vector<Result> results;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream fields(line);
    std::string mu2, lambda;
    Result result{};
    fields >> mu2 >> lambda >> result.status;
    EXPECT_TRUE(fields && fields.peek() == EOF) << "output line: " << line;
    result.mu2 = std::strtod(mu2.c_str(), nullptr);  // strtod also reads "nan"
    result.lambda = std::strtod(lambda.c_str(), nullptr);
    results.push_back(result);
  }
  return results;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// Whitespace runs (line breaks of wrapped help text included) as one space.
std::string collapse_whitespace(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (!std::isspace(static_cast<unsigned char>(c)))
      out += c;
    else if (!out.empty() && out.back() != ' ')
      out += ' ';
  }
  return out;
}

// The number after the first `label` in `text`; NaN if there is none.
double number_after(const std::string& text, const std::string& label) {
  const std::size_t at = text.find(label);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + label.size(), nullptr);
}

// Suite names start with "cli" so that `ctest -R cli` selects exactly these tests.
class cli : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::path(::testing::TempDir()) / "pwcontact_cli.XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    directory_ = pattern;
  }
  void TearDown() override { fs::remove_all(directory_); }

  fs::path path(const std::string& name) const { return directory_ / name; }

  void write_file(const std::string& name, const std::string& text) const {
    std::ofstream(path(name), std::ios::binary) << text;
  }

  std::string read_file(const std::string& name) const {
    std::ifstream file(path(name), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(file), {});
  }

  // The files of the test directory, to check that nothing was left behind.
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(directory_))
      names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  // Runs `pwcontact <arguments>` in the test directory through the shell,
  // so that `arguments` may redirect standard input ("< pairs.txt"; it is
  // /dev/null otherwise) and `shell_prefix` may set variables or start a
  // pipe ("cat pairs.txt |").
  Outcome run(const std::string& arguments, const std::string& shell_prefix = "") const {
    const std::string command = "cd " + quoted(directory_.string()) + " && exec </dev/null && " +
                                shell_prefix + " " + quoted(PWCONTACT_CLI) + " " + arguments +
                                " >stdout.txt 2>stderr.txt";
    const int status = std::system(command.c_str());
    Outcome result;
    result.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    result.out = read_file("stdout.txt");
    result.err = read_file("stderr.txt");
    fs::remove(path("stdout.txt"));
    fs::remove(path("stderr.txt"));
    return result;
  }

  // The standard output of `contact` on `text` (written to pairs.txt), expecting success.
  std::string contact_output(const std::string& text) {
    write_file("pairs.txt", text);
    const Outcome result = run("contact pairs.txt");
    EXPECT_EQ(result.exit_status, 0) << result.err;
    return result.out;
  }
  std::vector<Result> contact(const std::string& text) {
    return parse_results(contact_output(text));
  }

 private:
  fs::path directory_;
};

// ---------------------------------------------------------------------------
// Results

TEST_F(cli, SpheresRoundTripThroughAFile) {
  // Two spheres: mu = |r| / (a1 + a2), lambda = a1 / (a1 + a2).
  struct Spheres {
    double a1, a2, r[3];
  };
  const Spheres cases[] = {
      {1, 2, {6, 0, 0}}, {0.5, 1.5, {1, 2, 2}},        {3, 1, {0, 0, 1}},
      {1, 1, {0, 2, 0}}, {0.8, 1.7, {1.2, -0.7, 2.9}}, {2.5, 0.25, {-4, 3, -1}}};
  std::string text;
  for (const Spheres& s : cases)
    text += number_text(s.r[0]) + " " + number_text(s.r[1]) + " " + number_text(s.r[2]) + " " +
            sphere_text(s.a1) + " " + sphere_text(s.a2) + "\n";
  write_file("pairs.txt", text);

  const Outcome result = run("contact pairs.txt -o results.txt");
  ASSERT_EQ(result.exit_status, 0) << result.err;
  EXPECT_EQ(result.out, "");  // the results went to the file
  const std::vector<Result> results = parse_results(read_file("results.txt"));
  ASSERT_EQ(results.size(), std::size(cases));
  for (std::size_t i = 0; i < results.size(); ++i) {
    const Spheres& s = cases[i];
    const double distance = std::sqrt(s.r[0] * s.r[0] + s.r[1] * s.r[1] + s.r[2] * s.r[2]);
    const double mu = distance / (s.a1 + s.a2);
    // The batch path agrees with the reference path to 1e-13 relative (the
    // lane-by-lane tolerance), and 17 significant digits round-trip a double.
    EXPECT_NEAR(results[i].mu2, mu * mu, 1e-13 * mu * mu) << "pair " << i;
    EXPECT_NEAR(results[i].lambda, s.a1 / (s.a1 + s.a2), 1e-13) << "pair " << i;
    EXPECT_EQ(results[i].status, int(Status::ok)) << "pair " << i;
  }
  // The summary on standard error counts the pairs.
  EXPECT_TRUE(contains(result.err, std::to_string(std::size(cases)) + " pairs")) << result.err;
}

TEST_F(cli, CommentsAndBlankLinesAreSkipped) {
  const std::string pair1 = "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n";
  const std::string pair2 = "0 3 0\t" + sphere_text(1) + "\t" + sphere_text(1) + "\n";
  const std::string plain = contact_output(pair1 + pair2);
  const std::string commented = contact_output("# r12 q1 q2\n\n   # indented comment\n" + pair1 +
                                               " \t \n#\n  " + pair2 + "\n# trailing comment");
  EXPECT_EQ(commented, plain);
  EXPECT_EQ(parse_results(plain).size(), 2u);
}

TEST_F(cli, NonFiniteNumbersAreAnsweredWithAStatusNotAnError) {
  const std::string good = "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n";
  const std::string& q = unit_sphere;
  const std::string text = good +                                   //
                           "nan 0 0 " + q + " " + q + "\n" +        //
                           "1 0 0 inf 0 0 1 0 1 " + q + "\n" +      //
                           "1 -Infinity 0 " + q + " " + q + "\n" +  //
                           "1 0 0 " + q + " +INF 0 0 1 0 1\n" +     //
                           "NaN 0 0 " + q + " " + q + "\n" +        //
                           "1e400 0 0 " + q + " " + q + "\n" +      // beyond double range
                           good;
  write_file("pairs.txt", text);
  const Outcome result = run("contact pairs.txt");
  ASSERT_EQ(result.exit_status, 0) << result.err;

  std::istringstream lines(result.out);
  std::vector<std::string> output;
  for (std::string line; std::getline(lines, line);) output.push_back(line);
  ASSERT_EQ(output.size(), 8u);
  EXPECT_EQ(output[0], "4 0.33333333333333331 0");
  for (std::size_t i = 1; i <= 6; ++i)
    EXPECT_EQ(output[i], "nan nan " + std::to_string(int(Status::non_finite_input))) << i;
  EXPECT_EQ(output[7], output[0]);  // neighbours are unaffected
  EXPECT_TRUE(contains(result.err, "non_finite_input 6")) << result.err;
}

TEST_F(cli, MatricesThatAreNotPositiveDefiniteGetTheirStatus) {
  const std::vector<Result> results = contact("1 0 0 0 0 0 0 0 0 " + unit_sphere + "\n" + "1 0 0 " +
                                              unit_sphere + " -1 0 0 1 0 1\n");
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].status, int(Status::q1_not_positive_definite));
  EXPECT_EQ(results[1].status, int(Status::q2_not_positive_definite));
  EXPECT_TRUE(std::isnan(results[0].mu2) && std::isnan(results[1].lambda));
}

TEST_F(cli, LeadingPlusAndOtherNumberSpellingsAreAccepted) {
  const std::string q1 = "+1 0 0 1.0 0 1e0", q2 = "4 0 0 .4e1 0 4.";
  const std::vector<Result> results = contact("+6 -0 0 " + q1 + " " + q2 + "\r\n");
  ASSERT_EQ(results.size(), 1u);
  EXPECT_DOUBLE_EQ(results[0].mu2, 4);
}

// ---------------------------------------------------------------------------
// The paths and precisions agree

class cliRandomPairs : public cli {
 protected:
  void SetUp() override {
    cli::SetUp();
    write_file("pairs.txt", pairs_text(pwcontact::random_pairs(2000, 11)));
    reference_ = contact_file("");
  }
  std::vector<Result> contact_file(const std::string& options) {
    const Outcome result = run("contact " + options + " pairs.txt");
    EXPECT_EQ(result.exit_status, 0) << result.err;
    return parse_results(result.out);
  }
  // Every pair valid in both, mu2 within `mu2_relative`, lambda within `lambda_absolute`.
  void expect_agreement(const std::vector<Result>& results, double mu2_relative,
                        double lambda_absolute) const {
    ASSERT_EQ(results.size(), reference_.size());
    for (std::size_t i = 0; i < results.size(); ++i) {
      ASSERT_TRUE(pwcontact::is_valid(Status(results[i].status))) << "pair " << i;
      ASSERT_TRUE(pwcontact::is_valid(Status(reference_[i].status))) << "pair " << i;
      EXPECT_NEAR(results[i].mu2, reference_[i].mu2, mu2_relative * reference_[i].mu2) << i;
      EXPECT_NEAR(results[i].lambda, reference_[i].lambda, lambda_absolute) << i;
    }
  }
  std::vector<Result> reference_;  // the default: batch path in double
};

TEST_F(cliRandomPairs, FloatPrecisionAgreesWithDouble) {
  // The float batch path targets 1e-5 relative in mu2 against the reference
  // path on its own (float) input; rounding the 15 inputs to float adds
  // ~1e-7. Measured on 200,000 such pairs: 5.5e-7 for mu2, 5.6e-7 for lambda.
  expect_agreement(contact_file("--precision float"), 1e-5, 1e-5);
}

TEST_F(cliRandomPairs, ScalarReferencePathAgreesWithBatchPath) {
  // The lane-by-lane tolerance of the batch path against the reference path
  // (semi-axes in [0.5, 2]) is 1e-13 relative; measured: 1.7e-15. lambda,
  // the maximiser of a flat maximum, is less well determined than mu2, but
  // both paths end on Newton steps: measured 9e-16, allowed 1e-10.
  expect_agreement(contact_file("--scalar"), 1e-13, 1e-10);
}

TEST_F(cliRandomPairs, ResultsDoNotDependOnThreadCountOrInputKind) {
  const std::string one_thread = run("contact --threads 1 pairs.txt").out;
  EXPECT_EQ(run("contact --threads 2 pairs.txt").out, one_thread);
  EXPECT_EQ(run("contact --threads 2 < pairs.txt").out, one_thread);    // standard input
  EXPECT_EQ(run("contact --threads 2 - < pairs.txt").out, one_thread);  // '-' is standard input
  EXPECT_EQ(run("contact --threads 2", "cat pairs.txt |").out, one_thread);  // a pipe
}

// ---------------------------------------------------------------------------
// Malformed input: exit status 2, the line number, and no output file

struct MalformedCase {
  const char* name;
  std::string line;
  const char* complaint;
};

// Names the case in test names and failure messages.
void PrintTo(const MalformedCase& malformed, std::ostream* out) { *out << malformed.name; }

class MalformedLine : public cli, public ::testing::WithParamInterface<MalformedCase> {};

TEST_P(MalformedLine, StopsWithTheLineNumberAndLeavesNoOutputFile) {
  const std::string good = "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n";
  // Line 4: after a comment and a blank line, which count as lines too.
  write_file("pairs.txt", good + "# comment\n\n" + GetParam().line + "\n" + good);

  for (const bool output_existed : {false, true}) {
    if (output_existed) write_file("results.txt", "earlier results\n");
    const Outcome result = run("contact pairs.txt -o results.txt");
    EXPECT_EQ(result.exit_status, 2);
    EXPECT_TRUE(contains(result.err, "pairs.txt:4:")) << result.err;
    EXPECT_TRUE(contains(result.err, GetParam().complaint)) << result.err;
    EXPECT_EQ(result.out, "");
    if (output_existed) {
      EXPECT_EQ(read_file("results.txt"), "earlier results\n");  // untouched
      fs::remove(path("results.txt"));
    }
    EXPECT_EQ(files(), std::vector<std::string>{"pairs.txt"});  // no partial or temporary file
  }

  // From standard input the message names <stdin>, and nothing is written.
  const Outcome from_stdin = run("contact < pairs.txt");
  EXPECT_EQ(from_stdin.exit_status, 2);
  EXPECT_TRUE(contains(from_stdin.err, "<stdin>:4:")) << from_stdin.err;
  EXPECT_EQ(from_stdin.out, "");
}

INSTANTIATE_TEST_SUITE_P(
    cli, MalformedLine,
    ::testing::Values(
        MalformedCase{"TooFewNumbers", "1 0 0 " + unit_sphere + " 1 0 0 1 0", "found 14"},
        MalformedCase{"TooManyNumbers", "1 0 0 " + unit_sphere + " " + unit_sphere + " 7",
                      "found 16"},
        MalformedCase{"TrailingGarbage", "1 0 0 " + unit_sphere + " 1 0 0 1 0 1.0x", "'1.0x'"},
        MalformedCase{"DecimalComma", "1,5 0 0 " + unit_sphere + " " + unit_sphere, "'1,5'"},
        MalformedCase{"SignAfterPlus", "+-1 0 0 " + unit_sphere + " " + unit_sphere, "'+-1'"},
        MalformedCase{"Word", "one 0 0 " + unit_sphere + " " + unit_sphere, "'one'"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST_F(cli, MalformedLineIsFoundDeepInABigInputReadInParallel) {
  // ~18 MB: more than one block when read from a pipe (16 MiB), many pieces
  // per thread when mapped from a file.
  std::string text = pairs_text(pwcontact::random_pairs(60000, 3));
  text += "1 2 3\n";
  write_file("pairs.txt", text);
  const Outcome from_file = run("contact --threads 2 pairs.txt");
  EXPECT_EQ(from_file.exit_status, 2);
  EXPECT_TRUE(contains(from_file.err, "pairs.txt:60001: expected 15 numbers, found 3"))
      << from_file.err;
  const Outcome from_pipe = run("contact --threads 2", "cat pairs.txt |");
  EXPECT_TRUE(contains(from_pipe.err, "<stdin>:60001:")) << from_pipe.err;
}

// ---------------------------------------------------------------------------
// Help, version and command-line errors

TEST_F(cli, HelpListsEveryStatusCodeAndEveryOption) {
  for (const char* arguments : {"--help", "-h", "help", "help contact", "contact --help"}) {
    const Outcome result = run(arguments);
    EXPECT_EQ(result.exit_status, 0) << arguments;
    const std::string help = collapse_whitespace(result.out);
    for (int s = 0; s < pwcontact::status_count; ++s) {
      const std::string row = std::to_string(s) + " " + pwcontact::status_name(Status(s)) + " " +
                              pwcontact::status_description(Status(s));
      EXPECT_TRUE(contains(help, row)) << arguments << ": no row '" << row << "'";
    }
    for (const char* option : {"--precision double|float", "--iterations N", "--threads N",
                               "--isa auto|sse2|avx2|avx512", "--scalar", "-o, --output OUT"})
      EXPECT_TRUE(contains(help, option)) << arguments << ": " << option;
    EXPECT_TRUE(contains(help, "(default: double)")) << arguments;
  }
  const std::string demo_help = collapse_whitespace(run("demo --help").out);
  EXPECT_TRUE(contains(demo_help, "--pairs N number of random pairs (default: 2000000)"))
      << demo_help;
}

TEST_F(cli, VersionIsPrinted) {
  const Outcome result = run("--version");
  EXPECT_EQ(result.exit_status, 0);
  // "pwcontact MAJOR.MINOR.PATCH"
  const std::string prefix = "pwcontact ";
  ASSERT_EQ(result.out.compare(0, prefix.size(), prefix), 0) << result.out;
  const std::string version = result.out.substr(prefix.size());
  EXPECT_EQ(std::count(version.begin(), version.end(), '.'), 2) << version;
  EXPECT_EQ(version.find_first_not_of("0123456789."), version.size() - 1) << version;
  EXPECT_EQ(version.back(), '\n');
}

class UsageError : public cli, public ::testing::WithParamInterface<const char*> {};

TEST_P(UsageError, ExitsWithStatus2AndShowsTheUsage) {
  write_file("a.txt", "");
  write_file("b.txt", "");
  const Outcome result = run(GetParam());
  EXPECT_EQ(result.exit_status, 2);
  EXPECT_TRUE(contains(result.err, "Usage: pwcontact")) << result.err;
  EXPECT_EQ(result.out, "");
}

INSTANTIATE_TEST_SUITE_P(
    cli, UsageError,
    ::testing::Values("", "frobnicate", "--frobnicate", "help frobnicate", "contact --frobnicate",
                      "contact --threads", "contact --threads many", "contact --threads -1",
                      "contact --iterations 1001", "contact --precision half", "contact --isa avx9",
                      "contact --scalar=yes", "contact a.txt b.txt",
                      "contact --scalar --iterations 2 a.txt", "demo --pairs 0", "demo extra"));

TEST_F(cli, OutputThroughASymbolicLinkOrToADeviceIsWrittenInPlace) {
  write_file("pairs.txt", "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n");
  fs::create_directory(path("kept"));
  write_file("kept/results.txt", "earlier results\n");
  fs::create_symlink("kept/results.txt", path("link.txt"));
  ASSERT_EQ(run("contact pairs.txt -o link.txt").exit_status, 0);
  EXPECT_TRUE(fs::is_symlink(path("link.txt")));  // the link is kept, its target replaced
  EXPECT_EQ(read_file("kept/results.txt"), "4 0.33333333333333331 0\n");

  // Renaming a finished file over /dev/null would replace the device.
  ASSERT_EQ(run("contact pairs.txt -o /dev/null").exit_status, 0);
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

TEST_F(cli, InputAndOutputErrorsExitWithStatus1) {
  const Outcome missing_input = run("contact missing.txt");
  EXPECT_EQ(missing_input.exit_status, 1);
  EXPECT_TRUE(contains(missing_input.err, "missing.txt")) << missing_input.err;

  write_file("pairs.txt", "6 0 0 " + sphere_text(1) + " " + sphere_text(2) + "\n");
  const Outcome missing_directory = run("contact pairs.txt -o no/such/directory/results.txt");
  EXPECT_EQ(missing_directory.exit_status, 1);
  EXPECT_TRUE(contains(missing_directory.err, "cannot write no/such/directory/results.txt"))
      << missing_directory.err;
}

TEST_F(cli, BadInstructionSetInTheEnvironmentIsAUsageError) {
  write_file("a.txt", "");
  const Outcome result = run("contact a.txt", "PWCONTACT_ISA=avx9");
  EXPECT_EQ(result.exit_status, 2);
  EXPECT_TRUE(contains(result.err, "PWCONTACT_ISA=avx9")) << result.err;
}

TEST_F(cli, InstructionSetsTheCpuLacksAreAUsageError) {
  write_file("a.txt", "");
  int lacking = 0;
  for (pwcontact::Isa isa : {pwcontact::Isa::sse2, pwcontact::Isa::avx2, pwcontact::Isa::avx512})
    if (!pwcontact::isa_supported(isa)) {
      ++lacking;
      const Outcome result =
          run(std::string("contact --isa ") + pwcontact::isa_name(isa) + " a.txt");
      EXPECT_EQ(result.exit_status, 2);
      EXPECT_TRUE(contains(result.err, "does not support")) << result.err;
    }
  if (lacking == 0) GTEST_SKIP() << "this CPU runs every instruction set";
}

// ---------------------------------------------------------------------------
// The demo

TEST_F(cli, DemoReportsThroughputAndAccuracy) {
  for (const char* precision : {"double", "float"}) {
    const Outcome result = run(std::string("demo --pairs 3000 --precision ") + precision);
    ASSERT_EQ(result.exit_status, 0) << result.err;
    for (const char* word : {"pairs/s", "speed-up", "fallbacks", "p99.9", "median"})
      EXPECT_TRUE(contains(result.out, word)) << precision << ": " << word;
    // Each path's accuracy target against the reference path (see the
    // float and scalar agreement tests above).
    EXPECT_LE(number_after(result.out, "max "), precision == std::string("double") ? 1e-13 : 1e-5)
        << result.out;
  }
}

}  // namespace
