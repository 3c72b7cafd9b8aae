// Errors over the ranks of a communicator: a check that fails on some ranks
// only must fail on all of them before the next collective call, or the
// ranks that passed wait there for ever.
#pragma once

#include <mpi.h>

#include <string>

namespace pwcontact::mpi::detail {

// Collective. Returns when `error` is empty on every rank; otherwise throws
// std::invalid_argument on every rank, with the message of the lowest rank
// that has one: "<caller> (MPI, rank k): <error>".
void throw_if_any(MPI_Comm comm, const std::string& error, const char* caller = "screen_pairs");

}  // namespace pwcontact::mpi::detail
