// What main.ts gives a view after the server's `info`.

import type { BinaryMessage, ServerJson } from './protocol';

export interface View {
  json(message: ServerJson): void;
  binary(message: BinaryMessage): void;
}
