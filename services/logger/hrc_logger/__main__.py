from hrc_logger.main import main

raise SystemExit(main())
