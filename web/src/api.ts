// The server's services as the page calls them: gRPC-web to the gateway that
// served the page, the token (where there is one: a link's holder has none)
// in each call's `authorization` header.
import { createClient, type Client, type Interceptor } from "@connectrpc/connect";
import { createGrpcWebTransport } from "@connectrpc/connect-web";
import { PacsService, ServerService, SessionService, VolumeService } from "../gen/cinevol/v1/service_pb.js";

export interface Api {
  /**
   * Where the session lives, as CreateSession answered (behind a load
   * balancer, its own server): sent with the session's later calls so the
   * gateway takes them there. Empty: the gateway's server.
   */
  sessionAddress: string;
  sessions: Client<typeof SessionService>;
  volumes: Client<typeof VolumeService>;
  server: Client<typeof ServerService>;
  pacs: Client<typeof PacsService>;
}

export function connect(token: string | undefined, baseUrl: string): Api {
  const withToken: Interceptor = (next) => (request) => {
    if (token) request.header.set("authorization", `Bearer ${token}`);
    const inSession = request.service.typeName === SessionService.typeName && request.method.name !== "CreateSession";
    if (inSession && api.sessionAddress) request.header.set("cinevol-session-address", api.sessionAddress);
    return next(request);
  };
  const transport = createGrpcWebTransport({ baseUrl, useBinaryFormat: true, interceptors: [withToken] });
  const api: Api = {
    sessionAddress: "",
    sessions: createClient(SessionService, transport),
    volumes: createClient(VolumeService, transport),
    server: createClient(ServerService, transport),
    pacs: createClient(PacsService, transport),
  };
  return api;
}
