#include "tools/studio/web_server.h"

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <deque>
#include <fstream>
#include <sstream>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

namespace st::studio {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

Outgoing text_message(std::string json) {
  return {std::make_shared<const std::string>(std::move(json)), false, false};
}

Outgoing binary_message(std::string bytes, bool droppable) {
  return {std::make_shared<const std::string>(std::move(bytes)), true, droppable};
}

namespace {
// Length of a valid UTF-8 sequence at s[i], or 0.
std::size_t utf8_length(std::string_view s, std::size_t i) {
  const auto c = static_cast<unsigned char>(s[i]);
  std::size_t n = c >= 0xf0 && c <= 0xf4 ? 4 : c >= 0xe0 ? 3 : c >= 0xc2 && c < 0xe0 ? 2 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k)
    if ((static_cast<unsigned char>(s[i + k]) & 0xc0) != 0x80) return 0;
  return n;
}
}  // namespace

std::string json_string(std::string_view s) {
  std::string out;
  out.reserve(s.size() + 2);
  out += '"';
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char ch = s[i];
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c >= 0x80) {  // WebSocket text must be UTF-8: anything else becomes '?'
      const std::size_t n = utf8_length(s, i);
      if (n == 0) {
        out += '?';
      } else {
        out.append(s.substr(i, n));
        i += n - 1;
      }
      continue;
    }
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += ch;
        }
    }
  }
  out += '"';
  return out;
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

Outgoing error_message(std::string_view message) {
  return text_message("{\"type\":\"error\",\"message\":" + json_string(message) + "}");
}

std::string binary_header(BinaryKind kind, std::uint32_t frame) {
  std::string h(8, '\0');
  h[0] = static_cast<char>(kind);
  for (int i = 0; i < 4; ++i) h[static_cast<std::size_t>(4 + i)] = static_cast<char>((frame >> (8 * i)) & 0xff);
  return h;
}

namespace {

std::string_view mime_type(const std::filesystem::path& p) {
  const std::string ext = p.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".map") return "application/json";
  if (ext == ".png") return "image/png";
  if (ext == ".svg") return "image/svg+xml";
  return "application/octet-stream";
}

// A request target as a file under the web folder, or empty: only plain
// relative paths of [A-Za-z0-9._-/] without "..", no query.
std::filesystem::path file_for_target(const std::filesystem::path& root, std::string_view target) {
  if (const std::size_t q = target.find('?'); q != std::string_view::npos) target = target.substr(0, q);
  if (target.empty() || target[0] != '/') return {};
  std::string rel(target.substr(1));
  if (rel.empty()) rel = "index.html";
  if (rel.size() > 200 || rel.find("..") != std::string::npos || rel[0] == '/') return {};
  for (const char c : rel)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-' || c == '/')) return {};
  return root / rel;
}

}  // namespace

struct WebServer::Impl {
  net::io_context io{1};
  tcp::acceptor acceptor{io};
  net::signal_set signals{io, SIGINT, SIGTERM};
  ServerOptions options;
  PageHandler* handler = nullptr;
  int port = 0;
  mutable std::mutex pages_mutex;
  std::set<PagePtr> pages;
  std::atomic<std::uint64_t> next_id{1};

  void accept();
  void add_page(const PagePtr& p) {
    std::lock_guard<std::mutex> lock(pages_mutex);
    pages.insert(p);
  }
  void remove_page(const PagePtr& p) {
    std::lock_guard<std::mutex> lock(pages_mutex);
    pages.erase(p);
  }
};

namespace {

class WsPage final : public PageConnection, public std::enable_shared_from_this<WsPage> {
 public:
  WsPage(tcp::socket socket, WebServer::Impl* server, std::uint64_t id)
      : ws_(std::move(socket)), server_(server), id_(id) {}

  void start(http::request<http::string_body> req) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(server_->options.max_command_bytes);
    ws_.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return;  // a failed handshake ends only this connection
      self->open_ = true;
      self->server_->add_page(self);
      self->server_->handler->on_open(self);
      self->read();
    });
  }

  void send(Outgoing m) override {
    net::post(ws_.get_executor(), [self = shared_from_this(), m = std::move(m)]() mutable {
      self->enqueue(std::move(m));
    });
  }
  std::uint64_t id() const override { return id_; }

 private:
  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->close();  // closed, reset mid-message, a malformed frame, too big
      const std::string text = beast::buffers_to_string(self->buffer_.data());
      self->buffer_.consume(self->buffer_.size());
      if (self->ws_.got_text()) {
        self->server_->handler->on_text(self, text);
      } else {
        self->enqueue(error_message("binary messages are not commands"));
      }
      self->read();
    });
  }

  void enqueue(Outgoing m) {
    if (closed_) return;
    if (m.droppable) {
      // Keep at most a few frames waiting: drop the oldest droppable one
      // that is not being written.
      int waiting = 0;
      for (std::size_t i = writing_ ? 1 : 0; i < queue_.size(); ++i) waiting += queue_[i].droppable ? 1 : 0;
      if (waiting >= 4) {
        for (auto it = queue_.begin() + (writing_ ? 1 : 0); it != queue_.end(); ++it) {
          if (it->droppable) {
            queued_bytes_ -= it->bytes->size();
            queue_.erase(it);
            break;
          }
        }
      }
    }
    queued_bytes_ += m.bytes->size();
    queue_.push_back(std::move(m));
    if (queued_bytes_ > server_->options.max_queued_bytes) {
      std::fprintf(stderr, "scopetrack-studio: a page fell %zu bytes behind; disconnecting it\n", queued_bytes_);
      return close();
    }
    if (!writing_) write_next();
  }

  void write_next() {
    if (queue_.empty() || closed_) {
      writing_ = false;
      return;
    }
    writing_ = true;
    const Outgoing& m = queue_.front();
    ws_.binary(m.binary);
    ws_.async_write(net::buffer(*m.bytes), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->close();
      self->queued_bytes_ -= self->queue_.front().bytes->size();
      self->queue_.pop_front();
      self->write_next();
    });
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    queue_.clear();
    queued_bytes_ = 0;
    if (open_) {
      server_->remove_page(shared_from_this());
      server_->handler->on_close(shared_from_this());
    }
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
    beast::get_lowest_layer(ws_).socket().close(ec);
  }

  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer buffer_;
  WebServer::Impl* server_;
  std::uint64_t id_;
  std::deque<Outgoing> queue_;
  std::size_t queued_bytes_ = 0;
  bool writing_ = false, closed_ = false, open_ = false;
};

// One HTTP connection: files, or the upgrade to a page's WebSocket at /ws.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, WebServer::Impl* server) : stream_(std::move(socket)), server_(server) {}

  void read() {
    request_ = {};
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, request_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->shutdown();
      self->handle();
    });
  }

 private:
  void handle() {
    if (websocket::is_upgrade(request_)) {
      if (request_.target() != "/ws" && request_.target() != "/ws/") return respond(http::status::not_found, "text/plain", "no WebSocket here\n");
      stream_.expires_never();
      auto page = std::make_shared<WsPage>(stream_.release_socket(), server_, server_->next_id++);
      page->start(std::move(request_));
      return;
    }
    if (request_.method() != http::verb::get && request_.method() != http::verb::head)
      return respond(http::status::method_not_allowed, "text/plain", "GET only\n");
    const std::filesystem::path file = file_for_target(server_->options.web_dir, std::string_view(request_.target().data(), request_.target().size()));
    std::ifstream in(file, std::ios::binary);
    if (file.empty() || !in || std::filesystem::is_directory(file))
      return respond(http::status::not_found, "text/plain", "not found\n");
    std::ostringstream body;
    body << in.rdbuf();
    respond(http::status::ok, mime_type(file), body.str());
  }

  void respond(http::status status, std::string_view type, std::string body) {
    auto res = std::make_shared<http::response<http::string_body>>(status, request_.version());
    res->set(http::field::server, "scopetrack-studio");
    res->set(http::field::content_type, std::string(type));
    res->set(http::field::cache_control, "no-store");
    res->keep_alive(request_.keep_alive());
    if (request_.method() != http::verb::head) res->body() = std::move(body);
    res->prepare_payload();
    http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
      if (ec || !res->keep_alive()) return self->shutdown();
      self->read();
    });
  }

  void shutdown() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  http::request<http::string_body> request_;
  WebServer::Impl* server_;
};

}  // namespace

void WebServer::Impl::accept() {
  acceptor.async_accept(net::make_strand(io), [this](beast::error_code ec, tcp::socket socket) {
    if (!acceptor.is_open()) return;
    if (!ec) std::make_shared<HttpSession>(std::move(socket), this)->read();
    accept();
  });
}

WebServer::WebServer() : impl_(std::make_unique<Impl>()) {}
WebServer::~WebServer() = default;

Status WebServer::start(const ServerOptions& options, PageHandler* handler) {
  impl_->options = options;
  impl_->handler = handler;
  if (!std::filesystem::is_regular_file(options.web_dir / "index.html"))
    return make_error("the page is not built: no " + (options.web_dir / "index.html").string() +
                      " (build the project, or give --web DIR)");
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(options.address, ec);
  if (ec) return make_error("--address '" + options.address + "' is not an IP address");
  if (options.port < 0 || options.port > 65535) return make_error("--port must be in 0..65535");
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(options.port));
  impl_->acceptor.open(endpoint.protocol(), ec);
  if (!ec) impl_->acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) impl_->acceptor.bind(endpoint, ec);
  if (!ec) impl_->acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec)
    return make_error("cannot listen on " + options.address + ":" + std::to_string(options.port) + ": " +
                      ec.message());
  impl_->port = impl_->acceptor.local_endpoint().port();
  impl_->accept();
  impl_->signals.async_wait([this](beast::error_code, int) { stop(); });
  return Status::Ok();
}

int WebServer::port() const { return impl_->port; }

void WebServer::run() { impl_->io.run(); }

void WebServer::stop() {
  net::post(impl_->io, [this] {
    beast::error_code ec;
    impl_->acceptor.close(ec);
    impl_->io.stop();
  });
}

void WebServer::broadcast(const Outgoing& m) {
  std::set<PagePtr> pages;
  {
    std::lock_guard<std::mutex> lock(impl_->pages_mutex);
    pages = impl_->pages;
  }
  for (const PagePtr& p : pages) p->send(m);
}

void WebServer::post(std::function<void()> fn) { net::post(impl_->io, std::move(fn)); }

int WebServer::pages() const {
  std::lock_guard<std::mutex> lock(impl_->pages_mutex);
  return static_cast<int>(impl_->pages.size());
}

}  // namespace st::studio
