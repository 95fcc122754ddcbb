// The subcommands of `cinevol`. Each adds itself to the command line; its
// callback throws on failure and main prints the message.
#pragma once

#include <CLI/CLI.hpp>

namespace cinevol::cli {

void AddInfoCommand(CLI::App& app);

}  // namespace cinevol::cli
