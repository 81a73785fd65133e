// A throw-away PKI made by the `openssl` command at test time, shared by the TLS tests of one
// sculptd (tls_test.cc) and of a cluster's members (cluster/peer_tls_test.cc).
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace sculpt::testing {

// A throw-away PKI: a CA; a server certificate for localhost and 127.0.0.1; an expired one; a
// client certificate; a second CA that signed nothing the server presents; and a certificate
// of the first CA for another host only (elsewhere.pem: elsewhere.invalid).
class Pki {
 public:
  static Pki& Get() {
    static Pki pki;
    return pki;
  }
  std::filesystem::path dir;
  bool ok = false;
  std::string File(const char* name) const { return (dir / name).string(); }

 private:
  Pki() {
    dir = std::filesystem::temp_directory_path() / ("sculpt_tls_pki_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "san.ext") << "subjectAltName=DNS:localhost,IP:127.0.0.1\n";
    std::ofstream(dir / "ca.cnf") << "[ca]\ndefault_ca = c\n[c]\ndir = .\ndatabase = index.txt\n"
                                     "new_certs_dir = .\nserial = serial\ndefault_md = sha256\n"
                                     "policy = p\n[p]\ncommonName = supplied\n";
    std::ofstream(dir / "index.txt");
    std::ofstream(dir / "serial") << "01\n";
    const std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes ";
    const std::string script =
        "cd '" + dir.string() +
        "' && "
        "openssl req -x509" +
        ec +
        "-keyout ca.key -out ca.pem -days 2 -subj /CN=test-ca && "
        "openssl req -x509" +
        ec +
        "-keyout other-ca.key -out other-ca.pem -days 2 "
        "-subj /CN=other-ca && "
        "openssl req" +
        ec +
        "-keyout server.key -out server.csr -subj /CN=localhost && "
        "openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
        "-out server.pem -days 2 -extfile san.ext && "
        "openssl req" +
        ec +
        "-keyout expired.key -out expired.csr -subj /CN=localhost && "
        "openssl ca -batch -config ca.cnf -cert ca.pem -keyfile ca.key -in expired.csr "
        "-out expired.pem -startdate 20200101000000Z -enddate 20200102000000Z "
        "-extfile san.ext -notext && "
        "openssl req" +
        ec +
        "-keyout client.key -out client.csr -subj /CN=replica-1 && "
        "openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
        "-out client.pem -days 2 && "
        "echo subjectAltName=DNS:elsewhere.invalid > elsewhere.ext && "
        "openssl req" +
        ec +
        "-keyout elsewhere.key -out elsewhere.csr -subj /CN=elsewhere.invalid && "
        "openssl x509 -req -in elsewhere.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
        "-out elsewhere.pem -days 2 -extfile elsewhere.ext";
    // The log goes beside the certificates (the script's cd is inside the subshell), not into
    // the test's working directory.
    ok = std::system(("(" + script + ") > '" + dir.string() + "/openssl.log' 2>&1").c_str()) == 0;
    if (!ok) std::system(("cat '" + dir.string() + "/openssl.log'").c_str());
  }
  ~Pki() { std::filesystem::remove_all(dir); }
};

}  // namespace sculpt::testing
