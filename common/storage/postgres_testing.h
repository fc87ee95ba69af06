// Test helpers for the PostgreSQL map: a throw-away cluster started through scripts/pg.sh (initdb
// in a new folder under /tmp, run as the postgres user, a unix socket in that folder, stopped and
// removed at the end), databases made in it, and direct SQL to forge foreign, newer or damaged
// maps behind the store's back. Tests only.
#pragma once

#include <libpq-fe.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <string>

#include "common/util/status.h"

namespace placerec {
namespace testing_postgres {

// Runs `sql` on the database `url` names; an error saying why when it fails.
inline Status ExecPg(const std::string& url, const std::string& sql) {
  PGconn* conn = PQconnectdb(url.c_str());
  Status status;
  if (PQstatus(conn) != CONNECTION_OK) {
    status = Status::IoError("cannot connect to " + url + ": " + PQerrorMessage(conn));
  } else {
    PGresult* result = PQexec(conn, sql.c_str());
    const ExecStatusType code = PQresultStatus(result);
    if (code != PGRES_COMMAND_OK && code != PGRES_TUPLES_OK) {
      status = Status::IoError(sql + ": " + PQresultErrorMessage(result));
    }
    PQclear(result);
  }
  PQfinish(conn);
  return status;
}

// The first column of the first row of `sql`, as text; empty when there is none.
inline std::string QueryPg(const std::string& url, const std::string& sql) {
  PGconn* conn = PQconnectdb(url.c_str());
  std::string value;
  if (PQstatus(conn) == CONNECTION_OK) {
    PGresult* result = PQexec(conn, sql.c_str());
    if (PQresultStatus(result) == PGRES_TUPLES_OK && PQntuples(result) > 0) {
      value = PQgetvalue(result, 0, 0);
    }
    PQclear(result);
  }
  PQfinish(conn);
  return value;
}

// A cluster of scripts/pg.sh in its own folder.
class TestCluster {
 public:
  // Starts a cluster with `script` (the path of scripts/pg.sh). NotFound when the PostgreSQL
  // binaries are missing (callers skip then), another error when the cluster does not start.
  static StatusOr<std::unique_ptr<TestCluster>> Start(const std::string& script) {
    char pattern[] = "/tmp/placerec-pg-XXXXXX";
    const char* made = mkdtemp(pattern);
    if (made == nullptr) return Status::IoError("cannot make a folder under /tmp");
    std::unique_ptr<TestCluster> cluster(new TestCluster(script, made));
    const int code = cluster->Run("start");
    if (code == 3) {
      return Status::NotFound(
          "the PostgreSQL server binaries are missing (install postgresql-15: bash "
          "scripts/install-deps.sh)");
    }
    if (code != 0) {
      // The log goes with the cluster (below): what it said comes along in the message.
      return Status::Internal("scripts/pg.sh start " + cluster->dir_ + " failed (exit code " +
                              std::to_string(code) + "); it said:\n" + cluster->LogTail(30));
    }
    return cluster;
  }
  ~TestCluster() {
    Run("stop");
    std::remove((dir_ + ".log").c_str());
  }

  const std::string& dir() const { return dir_; }

  // The URL of `database` in the cluster.
  std::string Url(const std::string& database = "placerec") const {
    return "postgresql:///" + database + "?host=" + dir_ + "&port=5432&user=postgres";
  }

  // Creates an empty database `name` (lower-case letters, digits and '_'); its URL.
  StatusOr<std::string> CreateDatabase(const std::string& name) {
    const Status made = ExecPg(Url(), "CREATE DATABASE " + name);
    if (!made.ok()) return made;
    return Url(name);
  }

  // Stops the cluster and keeps its data (scripts/pg.sh down); Up() starts it again.
  bool Down() { return Run("down") == 0; }
  bool Up() { return Run("start") == 0; }

 private:
  TestCluster(std::string script, std::string dir)
      : script_(std::move(script)), dir_(std::move(dir)) {}
  // The last `lines` lines of DIR.log.
  std::string LogTail(size_t lines) const {
    std::ifstream in(dir_ + ".log");
    std::deque<std::string> tail;
    for (std::string line; std::getline(in, line);) {
      tail.push_back(line);
      if (tail.size() > lines) tail.pop_front();
    }
    std::string text;
    for (const std::string& line : tail) text += line + "\n";
    return text;
  }
  // Runs scripts/pg.sh COMMAND DIR, output to DIR.log; its exit code.
  int Run(const std::string& command) const {
    const std::string line =
        "bash '" + script_ + "' " + command + " '" + dir_ + "' >>'" + dir_ + ".log' 2>&1";
    const int status = std::system(line.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  std::string script_;
  std::string dir_;
};

}  // namespace testing_postgres
}  // namespace placerec
