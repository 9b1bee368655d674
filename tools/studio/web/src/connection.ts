// The WebSocket to scopetrack-studio (/ws on the server that served this page).

import { parseBinary, parseJson, type BinaryMessage, type ServerJson } from './protocol';

export interface ConnectionHandlers {
  json(message: ServerJson): void;
  binary(message: BinaryMessage): void;
  /** A text message that is not the JSON the contract describes. */
  garbled(what: string): void;
  closed(wasOpen: boolean): void;
}

export class Connection {
  private readonly socket: WebSocket;
  private open = false;

  constructor(handlers: ConnectionHandlers) {
    const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
    this.socket = new WebSocket(`${scheme}//${location.host}/ws`);
    this.socket.binaryType = 'arraybuffer';
    this.socket.addEventListener('open', () => {
      this.open = true;
    });
    this.socket.addEventListener('message', (event: MessageEvent) => {
      if (typeof event.data === 'string') {
        const message = parseJson(event.data);
        if (message) handlers.json(message);
        else handlers.garbled(`a text message that is not JSON: ${event.data.slice(0, 80)}`);
      } else {
        const message = parseBinary(event.data as ArrayBuffer);
        if (message) handlers.binary(message);
        else handlers.garbled('a binary message shorter than its 8-byte header');
      }
    });
    this.socket.addEventListener('close', () => {
      const wasOpen = this.open;
      this.open = false;
      handlers.closed(wasOpen);
    });
  }

  get isOpen(): boolean {
    return this.open && this.socket.readyState === WebSocket.OPEN;
  }

  /** Sends a text command; false when the connection is not open. */
  send(command: string): boolean {
    if (!this.isOpen) return false;
    this.socket.send(command);
    return true;
  }
}
