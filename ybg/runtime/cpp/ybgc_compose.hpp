// Several bridges in one process (ybgc compose, docs/compose.md): one YARP
// network, one ROS 2 context (one DDS participant) with one node per bridge,
// one RPC port of the process (/<name>/rpc:i), and every bridge as it runs
// alone: its own ports, threads (its loop, its ports' callbacks, its watcher
// of connections, its ROS 2 threads), rate, freshness, queue and totals, so
// that a bridge whose producer or reader stalls, or that is fed malformed
// Bottles, delays no other. Each bridge is the module ybgc generates for its
// config, its main() an entry of the process instead (Member::run); what it
// says is said under its module's name. A bridge that cannot start is said
// with its config and the others run; the process then exits 1 when stopped.
// ybgc writes this file and ybgc_compose.cpp beside a composed module.
#ifndef YBGC_COMPOSE_HPP
#define YBGC_COMPOSE_HPP

#include "ybgc_runtime.hpp"  // ybgc:runtime-import

#include <cstddef>

namespace ybgc {
namespace compose {

/// One bridge of the process.
struct Member
{
    const char* module;  // its module's name: its ports' prefix, its lines, its list in `stats`
    const char* config;  // its config file
    const char* at;      // where the config writes its output (file:line:column)
    /// Its module's main(), run in a thread of its own: the process gives it
    /// its program name and the process's ROS arguments, and hosts it.
    int (*run)(int argc, char* argv[]);
};

/// Runs the bridges `members` (in this order) in this process until SIGINT,
/// SIGTERM or `quit` on /<name>/rpc:i; the exit status: 0, 1 when a bridge
/// could not start (or YARP cannot be reached), 2 for a bad command line or
/// parameter (before anything opens). Each bridge runs with its config's
/// options and the parameters of its node (`--ros-args -p NODE:NAME:=VALUE`,
/// a --params-file keyed by node name).
int run(const char* name, const Member* members, std::size_t count, int argc, char* argv[]);

template <std::size_t N>
int run(const char* name, const Member (&members)[N], int argc, char* argv[])
{
    return run(name, members, N, argc, argv);
}

}  // namespace compose
}  // namespace ybgc

#endif  // YBGC_COMPOSE_HPP
