#include "io/output/output_files.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <system_error>

#include "src/core/error.h"
#include "src/core/interrupt_cleanup.h"

namespace nimbus {

namespace fs = std::filesystem;

namespace {

int rank_of(MPI_Comm comm) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    return rank;
}

// "<pid>-<8 hex digits>": the pid tells runs on one host apart, the random part runs on
// different hosts sharing a folder.
std::string draw_token() {
    char text[32];
    std::snprintf(text, sizeof(text), "%ld-%08x", static_cast<long>(::getpid()),
                  static_cast<unsigned>(std::random_device{}()));
    return text;
}

}  // namespace

OutputFiles::OutputFiles(MPI_Comm comm) : comm_(comm), rank_(rank_of(comm)) {
    char token[32] = {};
    if (rank_ == 0) draw_token().copy(token, sizeof(token) - 1);
    MPI_Bcast(token, sizeof(token), MPI_CHAR, 0, comm);
    token_ = token;
}

OutputFiles::~OutputFiles() {
    if (committed_ || rank_ != 0) return;
    std::error_code ec;
    for (const auto& [tmp, final_path] : files_) fs::remove(tmp, ec);
}

OutputFiles::Stale OutputFiles::stale_temporaries(const std::string& dir, const std::string& name) {
    Stale stale;
    std::error_code ec;
    const std::string prefix = name + ".";
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string f = it->path().filename().string();
        if (f.rfind(prefix, 0) != 0 || f.size() < 4 || f.compare(f.size() - 4, 4, ".tmp") != 0) continue;
        const size_t dash = f.rfind('-'), dot = f.rfind('.', dash);  // the token (draw_token)
        if (dash == std::string::npos || dot == std::string::npos) continue;
        const long pid = std::strtol(f.substr(dot + 1, dash - dot - 1).c_str(), nullptr, 10);
        if (pid <= 0 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM) continue;
        ++stale.files;
        std::error_code size_ec;
        stale.bytes += fs::file_size(it->path(), size_ec);
    }
    return stale;
}

std::string OutputFiles::add(const std::string& final_path) {
    files_.emplace_back(final_path + "." + token_ + ".tmp", final_path);
    // A signal does not run the destructor; rank 0 removes the temporaries, as there.
    if (rank_ == 0) interrupt_cleanup::add_file(files_.back().first);
    return files_.back().first;
}

std::string OutputFiles::with_final_names(std::string message) const {
    for (const auto& [tmp, final_path] : files_)
        for (size_t at = message.find(tmp); at != std::string::npos;
             at = message.find(tmp, at + final_path.size()))
            message.replace(at, tmp.size(), final_path);
    return message;
}

void OutputFiles::commit() {
    if (committed_) throw Error("output files are already committed");
    committed_ = true;  // from here on, commit() itself cleans up after a failure
    // No rank sees a final name before every rank has entered commit (and so is done with
    // the files): without this, rank 0 could rename while another rank still checks them.
    MPI_Barrier(comm_);
    std::string message;
    if (rank_ == 0) {
        const interrupt_cleanup::Deferred hold;  // a signal waits until the renames are done
        message = replace_finals();
        if (message.empty()) interrupt_cleanup::committed();  // nothing left to remove
    }
    check_collective(comm_, message.empty(), message);
}

// Rank 0's part of commit(): empty on success, else the error, with the folder as it was (the
// previous run's files restored under their names, no temporary and no backup left).
std::string OutputFiles::replace_finals() {
    std::error_code ec;
    std::string message;
    // A final name that is a folder (or anything but a file) would refuse the rename: say so
    // before touching anything.
    for (const auto& [tmp, final_path] : files_)
        if (fs::exists(fs::symlink_status(final_path, ec)) && !fs::is_regular_file(fs::symlink_status(final_path, ec))) {
            message = "cannot write output file '" + final_path + "': it exists and is not a file";
            break;
        }
    // Existing finals (a previous run's) are moved aside, so that a failed rename can put them
    // back: the folder then holds either this run's whole set or the previous files.
    std::vector<bool> backed_up(files_.size(), false);
    const auto backup = [&](size_t n) { return files_[n].second + "." + token_ + ".old"; };
    for (size_t n = 0; message.empty() && n < files_.size(); ++n) {
        if (!fs::exists(files_[n].second, ec)) continue;
        fs::rename(files_[n].second, backup(n), ec);
        if (ec) message = "cannot replace output file '" + files_[n].second + "': " + ec.message();
        else backed_up[n] = true;
    }
    size_t renamed = 0;
    for (; message.empty() && renamed < files_.size(); ++renamed) {
        const auto& [tmp, final_path] = files_[renamed];
        fs::rename(tmp, final_path, ec);
        if (ec) {
            message = "cannot write output file '" + final_path + "': " + ec.message();
            break;
        }
    }
    std::error_code ignored;
    if (!message.empty()) {
        for (size_t n = 0; n < files_.size(); ++n) {
            fs::remove(n < renamed ? files_[n].second : files_[n].first, ignored);
            if (backed_up[n]) fs::rename(backup(n), files_[n].second, ignored);
        }
        return message;
    }
    for (size_t n = 0; n < files_.size(); ++n)
        if (backed_up[n]) fs::remove(backup(n), ignored);
    return {};
}

}  // namespace nimbus
