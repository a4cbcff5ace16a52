#pragma once
// Writing the files feedid makes (result documents, reports, part programs, references, CSV, synthetic traces) so
// that a crash, a full disk or a kill never leaves a half-written file, and so that an output never overwrites an
// input or the history database.
//
// write_output_file() writes the new content into an unnamed temporary file in the target's folder (Linux O_TMPFILE;
// a named one, `.NAME.feedid-PID.tmp`, where the file system lacks it), checks every write, flushes it to the disk
// (fsync), names it and renames it over the target; then it flushes the folder. Until that rename the old file is
// untouched; after it the whole new file is there. Between naming the temporary and the rename (two system calls) a
// killed process leaves `.NAME.feedid-PID.tmp` behind; the next write of that output removes such files of processes
// that no longer run. A target that is not a regular file (a terminal, /dev/null, /dev/full, a FIFO) is written
// directly, every write checked.

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace feedid {

/// Replaces `path` with `text` atomically (see above). InputError "PATH: cannot write the file: REASON" (the OS's
/// reason: no space left on device, permission denied, ...) on any failure; the old file is then as it was and no
/// temporary file is left.
void write_output_file(const std::filesystem::path& path, std::string_view text);

/// `text` to stdout for "-", else write_output_file(). Every write to stdout is checked too.
void write_output(const std::string& path, std::string_view text);

/// A file a command reads or keeps, which no output of the command may overwrite.
struct GuardedFile {
    std::string what;      ///< how the message names it: "the trace", "the history database", "--result"
    std::string path;      ///< "" and "-" are skipped
    bool database{false};  ///< SQLite: its -wal, -shm and -journal companions are guarded too
};

/// An output of a command: the option that names it and its path ("" and "-" are skipped).
struct OutputPath {
    std::string option;  ///< "--json", "-o", ...
    std::string path;
};

/// Checks, before anything is written, that no output is the same file as a guarded file or as another output: the
/// same device and inode when both exist, else the same path once made absolute and resolved (symbolic links, "..").
/// InputError naming the option, the path and the file it would overwrite.
void require_separate_outputs(const std::vector<OutputPath>& outputs, const std::vector<GuardedFile>& guarded);

}  // namespace feedid
