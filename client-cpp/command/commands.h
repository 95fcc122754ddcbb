// The subcommands of `cinevol`. Each adds itself to the command line; its
// callback throws on failure and main prints the message.
#pragma once

#include <CLI/CLI.hpp>

namespace cinevol::cli {

// --resample-uneven's help, alike in every command that may read a DICOM series.
inline constexpr const char* kResampleUnevenHelp =
    "A DICOM series whose slices lie unevenly apart is resampled onto an even grid (its smallest gap, a note "
    "naming the largest) instead of refused";

void AddDemoCommand(CLI::App& app);
void AddHealthCommand(CLI::App& app);
void AddInfoCommand(CLI::App& app);
void AddLoadtestCommand(CLI::App& app);
void AddMeasurementsCommand(CLI::App& app);  // measurements store, load
void AddMovieCommand(CLI::App& app);
void AddPacsCommand(CLI::App& app);
void AddPickCommand(CLI::App& app);
void AddPlayCommand(CLI::App& app);
void AddShareCommands(CLI::App& app);  // share, shares, revoke, handover, watch
void AddSnapshotCommand(CLI::App& app);
void AddSliceCommand(CLI::App& app);
void AddRenderCommand(CLI::App& app);
void AddStatusCommand(CLI::App& app);
void AddViewCommand(CLI::App& app);
void AddVolumesCommand(CLI::App& app);

}  // namespace cinevol::cli
