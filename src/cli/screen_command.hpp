// `pwcontact screen` over the ranks of a distributed run (pwcontact-mpi):
// the command's parsing, reading and writing as one process does them, the
// screening step given by the caller. Every rank runs the command with the
// same arguments; the root alone opens the outputs, reads the input and
// writes the results, so that they are those of `pwcontact screen`, byte
// for byte.
#pragma once

#include <functional>
#include <string>

#include "cli/command_line.hpp"
#include "pwcontact/screen.hpp"

namespace pwcontact::cli {

// The collective steps, each called once by every rank, in this order.
struct ScreenRanks {
  bool root = true;  // reads the input and writes the output
  // The root's exit status (0: go on) to every rank.
  std::function<int(int root_status)> share_status;
  // The root's box to every rank.
  std::function<Box(const Box& root_box)> share_box;
  // The screen of the root's particles (the others pass none) over the
  // ranks, every pair on the root as screen_pairs orders them; throws
  // std::invalid_argument on every rank for bad input.
  std::function<ScreenReport(const ParticleStore&, const Box&, const ScreenOptions&,
                             ScreenedPairs&)>
      screen;
  // The summary's lines for the report the root's screen returned.
  std::function<std::string(const ScreenReport&)> describe;
};

// Runs `pwcontact screen ARGUMENTS` on this rank; throws CommandError as the
// command does (on every rank for what every rank parses; on the root for
// its input and output, the others then returning the same exit status).
ExitStatus run_screen_over(const Arguments& arguments, const ScreenRanks& ranks);

}  // namespace pwcontact::cli
