"""A multipart/form-data body for the evaluation scripts that post forms to the service."""
import uuid


def multipart(parts):
    """The body of `parts`, (name, data, filename or None, content type) each in order (a name
    may repeat), and its content type."""
    boundary = uuid.uuid4().hex
    body = bytearray()
    for name, data, filename, ctype in parts:
        body += f"--{boundary}\r\n".encode()
        disposition = f'form-data; name="{name}"' + (f'; filename="{filename}"' if filename else "")
        body += f"Content-Disposition: {disposition}\r\nContent-Type: {ctype}\r\n\r\n".encode()
        body += data + b"\r\n"
    body += f"--{boundary}--\r\n".encode()
    return bytes(body), f"multipart/form-data; boundary={boundary}"
